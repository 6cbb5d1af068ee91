"""Generators written apart from the twins and the estimator, for tests and benchmarks."""
