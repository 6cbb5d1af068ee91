"""The fits on the steps table: creep curve, friction from the phase, contact mechanics."""
