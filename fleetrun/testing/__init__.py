"""Fixtures for tests and benchmarks: generated recordings with known hidden physics.

Not used by the commands; kept in the package so tests, benchmarks and validation scripts
share one generator (``fleetrun.testing.recordings``).
"""
