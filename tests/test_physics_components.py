"""Each loss component against a hand calculation from its cited equation.

Hand values are computed here step by step from the printed formula with round inputs, so
the tolerance is floating-point only (1e-12 relative), except where a published value is
quoted (air viscosity: 4 significant figures in the U.S. Standard Atmosphere table).
"""
import math

import numpy as np
import pytest

from fleetrun.physics import bearings, gear_mesh, lubricant, seals, windage
from fleetrun.physics.floor import mark_negative, zero_nan

REL = 1e-12


def test_walther_passes_through_its_two_points():
    # thesis Eq. 5.13: the fit reproduces the data points of B.7 (80W90: 139 cSt at 40 C, 15 at 100 C)
    nu = lubricant.walther_viscosity_m2_s([40.0, 100.0], "80W90")
    assert nu == pytest.approx([139e-6, 15e-6], rel=1e-12)


def test_walther_hand_calculation_at_70C():
    # thesis Eq. 5.14 by hand for ATF (7.2 cSt at 373.15 K, 35 cSt at 313.15 K)
    y1, y2 = math.log10(math.log10(8.0)), math.log10(math.log10(35.8))
    B = (y1 - y2) / (math.log10(373.15) - math.log10(313.15))
    A = y1 - B * math.log10(373.15)
    want = (10 ** (10 ** (A + B * math.log10(343.15))) - 0.8) * 1e-6
    assert lubricant.fluid_properties("ATF", 70.0).nu_m2_s == pytest.approx(want, rel=1e-12)
    assert 7.2e-6 < want < 35e-6  # between the two data points, as 70 C is


def test_sutherland_air_viscosity_matches_standard_atmosphere():
    # thesis Eq. 5.15b; U.S. Std. Atmosphere 1976 table: 1.7894e-5 Pa s at 288.15 K
    assert lubricant.sutherland_air_viscosity_Pa_s(288.15) == pytest.approx(1.7894e-5, rel=2e-4)


def test_densities_with_thermal_expansion():
    # thesis Eqs 5.18-5.19: rho = rho_std / (1 + 7e-4 (T - 288.2))
    assert lubricant.oil_density_kg_m3(343.15, 887) == pytest.approx(887 / (1 + 7e-4 * 54.95), rel=REL)
    # B.7's air density has the opposite sign (quirk): denser when hot
    assert lubricant.air_density_thesis_kg_m3(343.15) == pytest.approx(1.225 / (1 - 7e-4 * 54.95), rel=REL)


def test_operating_temperature_is_ambient_plus_50K():
    assert lubricant.operating_temperature_C(20.0) == 70.0  # thesis Sec. 3.1.2


def test_unknown_lubricant_lists_valid_names():
    with pytest.raises(Exception) as err:
        lubricant.fluid_properties("80W-90")
    assert "80W90" in str(err.value) and "ATF" in str(err.value)


def test_cylindrical_windage():
    # thesis Eq. 5.1: pi/4 mu D^3 L / a omega with mu=2e-5, D=0.05, L=0.1, a=0.001, omega=100
    want = math.pi / 4 * 2e-5 * 0.05 ** 3 * 0.1 / 0.001 * 100
    assert windage.cylindrical_windage_torque_Nm(2e-5, 0.05, 0.1, 0.001, 100.0) == pytest.approx(want, rel=REL)


def test_spherical_windage():
    # thesis Eq. 5.2: 4 pi^2/45 mu n r^4/(R - r)
    want = 4 * math.pi ** 2 / 45 * 2e-5 * 1000 * 0.07 ** 4 / 0.01
    assert windage.spherical_windage_torque_Nm(2e-5, 1000.0, 0.07, 0.08) == pytest.approx(want, rel=REL)


def test_helical_gear_windage():
    # thesis Eq. 5.5 (B.1 form), X = 0.25 to exercise both fluid terms
    fluid = 0.25 * 850 * 1e-5 ** .15 + 0.75 * 1.2 * 1.6e-5 ** .15
    want = 1.069e-4 * 0.7 * (1 + 2.3 * 0.03 / 0.1) * 2000 ** 1.85 * (0.25 ** 4.7 - 0.05 ** 4.7) * fluid
    got = windage.helical_gear_windage_torque_Nm(2000.0, 0.03, 0.1, 0.25, 0.05, 0.25, 850, 1e-5, 1.2, 1.6e-5)
    assert got == pytest.approx(want, rel=REL)


def test_bevel_gear_windage_dudley():
    # thesis Eqs 5.8/5.10 (Dudley, inches): pinion and ring-gear forms
    mix = (0.2 * 0.03 + 0.8 * 2e-5) / 2e-5
    base = 15 / 0.746 * mix * (3.0) ** 2 / (1000 / 60 * 2 * math.pi) * (2 * 1.5 / 100) ** 4
    lead = 5 * 2.0 / 100 * (1 + 7.0 / math.sqrt(math.tan(0.6)))
    pinion = windage.bevel_gear_windage_torque_Nm(3000.0, 1.5, 2.0, 7.0, 0.6, 0.2, 0.03, 2e-5)
    assert pinion == pytest.approx(base * (lead + 2 * 1.5 / 100) * 745.7, rel=1e-12)
    ring = windage.bevel_gear_windage_torque_Nm(3000.0, 1.5, 2.0, 7.0, 0.6, 0.2, 0.03, 2e-5, inner_radius_in=1.0)
    assert ring == pytest.approx(base * (lead + 2 * (1.5 ** 5 - 1) / 1.5 ** 4 / 100) * 745.7, rel=1e-12)
    assert windage.dudley_face_factor(12, 1.0) == pytest.approx(7.7782 - 0.1682 * 6, rel=REL)


def test_helical_mesh_efficiency():
    # thesis Eq. 5.6 (B.1 as printed) with mu 0.04, C 0.3, alpha 20 deg, G 3, e 1.1337
    G, C, a, e = 3.0, 0.3, math.radians(20), 1.1337
    want = 1 - ((0.04 / (2 * C / (1 + G) * math.cos(a))) * abs(1 - 1 / G) * (C * math.sin(a) / (1 + G))
                * (1 + G ** 2) / abs(1 - G) * (1 - e + e ** 2))
    assert gear_mesh.helical_mesh_efficiency(0.04, C, a, G) == pytest.approx(want, rel=REL)
    assert 0.95 < want < 1


def test_hypoid_mesh():
    # thesis Eq. 5.9: sliding speed (ft/min), Dudley Fig. 12.8 fit, Dudley Eq. 12.36
    v = gear_mesh.hypoid_sliding_speed_fpm(1200.0, 0.2, 1.0, 12)
    assert v == pytest.approx(1200 / 12 * math.sqrt(0.04 + 0.25) * 12, rel=REL)
    f = gear_mesh.dudley_friction_coefficient(v)
    assert f == pytest.approx(0.8 / math.sqrt(v + 100), rel=REL)
    eta = gear_mesh.hypoid_mesh_efficiency(f, math.radians(20), 0.9, 0.4)
    assert eta == pytest.approx((math.cos(math.radians(20)) + f * math.tan(0.4))
                                / (math.cos(math.radians(20)) + f * math.tan(0.9)), rel=REL)
    assert eta < 1  # pinion spiral larger than gear spiral: a loss


def test_taper_roller_bearing_moment():
    # thesis Eq. 5.11, Khonsari & Booser Eqs 15.1-15.5, printed units
    P = bearings.bearing_load_thesis(100.0, 1.5, math.radians(20), bearings=2, multiplier=2)
    assert P == pytest.approx(100 * 1.5 / math.cos(math.radians(20)) / 2 * 2, rel=REL)
    d, D = 57.15, 81 / 68 * 57.15
    want = 5e-4 * 0.0018 * P * d + 1.6e-8 * 8 * (0.5 * (d + D)) ** 3 + 1e-3 * (((d + D) / 20) ** 2 + 25)
    assert bearings.taper_roller_moment(P, 1500.0, d, D, 36.6e-6) == pytest.approx(want, rel=REL)


def test_bearing_viscous_branch_switches_as_printed():
    # the printed switch compares omega * nu (SI) with 2000: silent at road speeds
    slow = bearings.viscous_moment(5000.0, 36.6e-6, 60.0)
    assert slow == pytest.approx(1.6e-8 * 8 * 60 ** 3, rel=REL)
    fast = bearings.viscous_moment(1e9, 1.0, 60.0)  # omega nu > 2000
    assert fast == pytest.approx(1e-10 * 8 * (2 * math.pi / 60 * 1e9) ** (2 / 3) * 60 ** 3, rel=REL)


def test_seal():
    # thesis Eq. 5.12: 2 pi r^2 F', F' = 50 + 170 s
    assert seals.seal_tangential_force_N_per_m(0.5) == 135
    assert seals.seal_torque_Nm(0.02, 220.0) == pytest.approx(2 * math.pi * 0.0004 * 220, rel=REL)


def test_efficiency_floor_b6():
    eta, torque = mark_negative(np.array([0.9, -0.1, np.nan]), np.array([1.0, 2.0, 3.0]))
    assert np.isnan(eta[1]) and np.isnan(torque[1]) and eta[0] == 0.9 and torque[2] == 3.0
    eta, torque = zero_nan(eta, torque)
    assert eta.tolist() == [0.9, 0.0, 0.0] and torque.tolist() == [1.0, 0.0, 0.0]


def test_vecto_generic_axle_loss_map():
    # VECTO generic axle: Td0 = 52.5 + 15 i; loss = 0.5 Td0 + 0.5 Td0 n_out/150 + |T_out|(1/0.98 - 1)
    from fleetrun.differential import efficiency, reference_capacity_Nm
    from fleetrun.differential.baselines import vecto_generic_output_torque_Nm

    i, t_in, n_in = 3.0, 500.0, 1500.0
    t_out = vecto_generic_output_torque_Nm(t_in, n_in / i, i)
    td0 = 52.5 + 15 * i
    loss = 0.5 * td0 + 0.5 * td0 * (n_in / i) / 150 + abs(t_out) * (1 / 0.98 - 1)
    assert t_in * i == pytest.approx(t_out + loss, rel=1e-12)  # the map's balance holds
    tf = t_in / reference_capacity_Nm("HD_RWD")
    eta = float(efficiency("HD_RWD", tf, n_in, i, physics="vecto-generic"))
    assert eta == pytest.approx(t_out / (t_in * i), rel=1e-12)


def test_kim_torque_scale():
    # thesis Sec. 5.2.1.A, B.1's own example: GM V6 285 N m x converter 3 x first gear 4.69
    from fleetrun.differential import kim_torque_scale_Nm, reference_capacity_Nm

    assert kim_torque_scale_Nm(285, 3.0, 4.69) == pytest.approx(285 * 4.69 * 3, rel=REL)
    assert reference_capacity_Nm("LD_FWD") == pytest.approx(285 * 4.69 * 3, rel=REL)
