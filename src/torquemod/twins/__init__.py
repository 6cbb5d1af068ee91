"""Digital twins, imported by no measurement package."""
