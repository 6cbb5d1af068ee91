"""Signal-processing steps of the chain: numpy arrays in, numpy arrays out, ``fs`` in Hz."""
