"""Unit conversions used across fleetrun (exact by definition), one owner each.

- international mile: 1609.344 m (NIST SP 811, B.8)
- US liquid gallon: 3.785411784 L (NIST SP 811, B.8)
"""
METERS_PER_MILE = 1609.344
LITERS_PER_GALLON = 3.785411784
