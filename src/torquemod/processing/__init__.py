"""The processing chain: recordings -> per-cycle and per-step tables (filters, phase,
revolutions)."""
