"""The results folder of a rig experiment: written atomically, read back."""
