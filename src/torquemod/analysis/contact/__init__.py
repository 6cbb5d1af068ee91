"""Wheel-rail contact models: Polach creep forces, Kalker coefficients, Hertz ellipse."""
