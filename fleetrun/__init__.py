"""fleetrun: differential efficiency, drive-cycle fuel and fleet fuel-tax forecasting.

The core is the fundamental differential efficiency model of J. R. Vaughn's 2012 UT Austin
thesis (TxDOT Project 0-5974)."""

__version__ = "0.1.0"
