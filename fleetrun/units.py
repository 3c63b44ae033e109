"""Unit conversions and physical constants used across fleetrun (exact by definition), one
owner each: everything else imports them (tests/test_one_owner.py searches for re-typings).

- international mile: 1609.344 m (NIST SP 811, B.8)
- US liquid gallon: 3.785411784 L (NIST SP 811, B.8)
- revolutions per minute and radians per second: 1 rpm = 2 pi / 60 rad/s
- standard acceleration of gravity g_n = 9.80665 m/s^2 (3rd CGPM, 1901; NIST SP 811, B.8)

>>> round(3000 * RAD_S_PER_RPM, 4)     # 3000 rpm in rad/s
314.1593
>>> round(100.0 * RPM_PER_RAD_S, 2)    # 100 rad/s in rpm
954.93
"""
import math

METERS_PER_MILE = 1609.344
LITERS_PER_GALLON = 3.785411784
#: multiply a speed in rpm by this to get rad/s
RAD_S_PER_RPM = 2.0 * math.pi / 60.0
#: multiply an angular speed in rad/s by this to get rpm
RPM_PER_RAD_S = 60.0 / (2.0 * math.pi)
STANDARD_GRAVITY_M_S2 = 9.80665
