"""Thesis B.5 two-speed box (Kim's Eaton Fuller FRO16210C auxiliary section, adapted by Vaughn).

Line references "B.5 l.N" are line numbers of the thesis text (the seed 000_*.txt, with its
blank lines), where B.5 runs from l.6113 to l.8029.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import fleetrun.physics.two_speed_box as box
from fleetrun.errors import InputError
from fleetrun.physics.two_speed_box import (
    auxiliary_box,
    bearing_f1_branch,
    gear_pair_efficiency,
    load_geometry,
    oil_and_air_properties,
    output_seal_loss,
)

MEASURED_LOW = 43 / 34 * 62 / 16  # 4.900735294117647


def _sind(x):
    return math.sin(math.radians(x))


def _cosd(x):
    return math.cos(math.radians(x))


def _tand(x):
    return math.tan(math.radians(x))


# --------------------------------------------------------------------------------------------
# hand calculations of printed sub-results
# --------------------------------------------------------------------------------------------

def _gpeff_by_hand(t_D, t_d, gamma, OD_D, OD_d):
    """B.5 l.6277-6455, written out again from the printed statements:
    alpha_t = atand(tand(alpha_n)/cosd(gamma)); R_p_D = C/(1+t_d/t_D); R_b_D = R_p_D*cosd(alpha_n);
    R_p_d = C - R_p_D; R_b_d = R_p_d*cosd(alpha_n);
    beta_D = (sqrt(OD_D^2-(2R_b_D)^2) - 2R_p_D sind(alpha_t))/(2R_b_D);
    beta_d = (sqrt(OD_d^2-(2R_b_d)^2) - 2R_p_d sind(alpha_t))/(2R_b_D);
    GPEff = 1 - cosd(alpha_t)/(cosd(alpha_n)cosd(gamma)) * (1+1/G) * mu/2 * (bD^2+bd^2)/(bD+bd)
    with C = 149.5044 mm, alpha_n = 20 deg, mu_fGP = 0.06."""
    C, alpha_n, mu = 149.5044, 20.0, 0.06
    G = t_d / t_D
    alpha_t = math.degrees(math.atan(_tand(alpha_n) / _cosd(gamma)))
    R_p_D = C / (1 + t_d / t_D)
    R_b_D = R_p_D * _cosd(alpha_n)
    R_p_d = C - R_p_D
    R_b_d = R_p_d * _cosd(alpha_n)
    b_D = (math.sqrt(OD_D ** 2 - (2 * R_b_D) ** 2) - 2 * R_p_D * _sind(alpha_t)) / (2 * R_b_D)
    b_d = (math.sqrt(OD_d ** 2 - (2 * R_b_d) ** 2) - 2 * R_p_d * _sind(alpha_t)) / (2 * R_b_D)
    return 1 - (_cosd(alpha_t) / (_cosd(alpha_n) * _cosd(gamma))) * (1 + 1 / G) * (mu / 2) * (
        (b_D ** 2 + b_d ** 2) / (b_D + b_d))


def test_initial_pair_efficiency_by_hand():
    # B.5 GPEff_i_aux: 34/43 teeth, helix 32.5 deg, OD 142.24 / 175.1584 mm
    hand = _gpeff_by_hand(34, 43, 32.5, 142.24, 175.1584)
    ported = gear_pair_efficiency(34, 43, 32.5, 142.24, 175.1584, 149.5044, 20.0, 0.06)
    assert ported == pytest.approx(hand, rel=1e-14)
    assert hand == pytest.approx(0.9924737571857507, rel=1e-12)


def test_low_pair_efficiency_by_hand():
    # B.5 GPEff_L_aux for the measured box: 16/62 teeth, helix 12.5 deg, OD 69.469 / 239.776 mm;
    # G_L_aux = toospd_lo_gear/G_i_aux = 62/16, so the drive gear scaling (l.6406) is 1.
    hand = _gpeff_by_hand(16, 62, 12.5, 69.469, 239.776)
    ported = gear_pair_efficiency(16, 62, 12.5, 69.469, 239.776, 149.5044, 20.0, 0.06,
                                  gear_ratio=MEASURED_LOW / (43 / 34),
                                  drive_scale=(MEASURED_LOW / (43 / 34)) / (62 / 16))
    assert ported == pytest.approx(hand, rel=1e-14)
    assert hand == pytest.approx(0.9901106128056931, rel=1e-12)


def test_output_seal_loss_by_hand():
    # B.5 l.6251: torqueloss_seal_output = 2*pi*(r_sh_output*(10^-3))^2*F_tan,
    # r_sh_output = 70.0532/2 mm, F_tan = 150 N/m  ->  2*pi*0.0350266^2*150 N m
    hand = 2 * math.pi * 0.0350266 ** 2 * 150
    assert output_seal_loss(70.0532, 150) == pytest.approx(hand, rel=1e-14)
    assert hand == pytest.approx(1.15629086, rel=1e-8)


def test_oil_temperature_and_viscosity_by_hand():
    # B.5 l.6471-6503: T_oil = (72-32)*5/9+273.1+50; A = (T_oil/373.1)^-2.965198089;
    # mu_oil = (18.3^A - 0.7)*1e-6 m2/s; rho_oil = (-0.0007*(T_oil-273.1)+0.860)*999
    T_oil = (72 - 32) * 5 / 9 + 273.1 + 50
    A = (T_oil / 373.1) ** -2.965198089
    rho_air, mu_air, rho_oil, mu_oil, mu_oil_dyn = oil_and_air_properties(72.0, 50.0)
    assert T_oil == pytest.approx(345.3222222, rel=1e-9)
    assert mu_oil == pytest.approx((18.3 ** A - 0.7) * 1e-6, rel=1e-14)
    assert rho_oil == pytest.approx((-0.0007 * (T_oil - 273.1) + 0.860) * 999, rel=1e-14)
    assert mu_oil_dyn == pytest.approx(mu_oil * rho_oil * 1000, rel=1e-14)
    assert rho_air == pytest.approx(101325 / (287.058 * T_oil), rel=1e-14)


def test_low_gear_at_standstill_is_the_two_meshes_less_the_seal():
    # At 0 rpm every windage and bearing loss of B.5's low gear is 0 (RPM^1.85 = 0,
    # (RPM*mu)^0.62 = 0), so torque_d_OS_aux = T*G_i*GPEff_i*G_L*GPEff_L - seal and
    # trans_efficiency_aux = GPEff_i*GPEff_L - seal/(T*peak_torque*G_i*G_L).
    g_i, g_l = 43 / 34, MEASURED_LOW / (43 / 34)
    gp_i = _gpeff_by_hand(34, 43, 32.5, 142.24, 175.1584)
    gp_l = _gpeff_by_hand(16, 62, 12.5, 69.469, 239.776)
    seal = 2 * math.pi * 0.0350266 ** 2 * 150
    T = np.array([0.25, 0.5, 1.0])
    eta, torque_out, rpm_out = auxiliary_box(T, 0.0, MEASURED_LOW, "low")
    expected = gp_i * gp_l - seal / (T * 5794.088 * g_i * g_l)
    np.testing.assert_allclose(eta, expected, rtol=1e-12)
    # output fraction = output torque / peak_torque / G_i / G_L  (B.5 l.7401)
    np.testing.assert_allclose(torque_out, eta * T, rtol=1e-12)
    np.testing.assert_array_equal(rpm_out, 0.0)


# --------------------------------------------------------------------------------------------
# branch semantics of the bearing load factor (MATLAB chained comparisons)
# --------------------------------------------------------------------------------------------

def test_load_factor_branch_is_matlab_chained_comparison():
    # B.5 l.7090-7102 (and five more copies): if LF < 0.47 / elseif 0.47 <= LF < 0.94 / elseif 0.94 <= LF < 2.0 / else
    # (0.47 <= LF) < 0.94 is false for LF >= 0.47, (0.94 <= LF) < 2.0 is always true.
    lf = np.array([0.0, 0.3, 0.4699, 0.47, 0.6, 0.93, 0.94, 1.2, 1.99, 2.0, 5.0, np.inf, np.nan])
    branch = bearing_f1_branch(lf)
    np.testing.assert_array_equal(branch, [1, 1, 1, 3, 3, 3, 3, 3, 3, 3, 3, 3, 2])
    # NaN: NaN < 0.47 is false, (0.47 <= NaN) = 0 < 0.94 is true -> the second polynomial
    assert bearing_f1_branch(np.nan) == 2
    # the whole-array form printed for bearings #8/#10 in low gear (l.7147, l.7237) gives the
    # same branches
    np.testing.assert_array_equal(bearing_f1_branch(lf, whole_array_third_test=True), branch)


def test_load_factor_values():
    lf = np.array([0.3, 0.6, 0.94, 1.2, 2.5, np.nan])
    f1 = box._bearing_f1(lf)
    third = -0.13538 + 0.96978 * lf + 0.028991 * lf ** 2
    np.testing.assert_array_equal(f1[0], 0.06)
    np.testing.assert_allclose(f1[1:5], third[1:5], rtol=1e-15)  # not the 2nd polynomial
    assert f1[1] != pytest.approx(-0.13443 - 0.15316 * 0.6 + 1.238 * 0.36)
    assert np.isnan(f1[5])


# --------------------------------------------------------------------------------------------
# shape, broadcasting, gears, floors
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("gear", ["low", "high"])
def test_broadcasting_matches_scalar_calls(gear):
    T = np.array([[0.0], [0.1], [0.6], [1.0]])
    n = np.array([0.0, 750.0, 2500.0])
    eta, tq, rpm = auxiliary_box(T, n, MEASURED_LOW, gear)
    assert eta.shape == tq.shape == rpm.shape == (4, 3)
    for i in range(4):
        for j in range(3):
            e, t, r = auxiliary_box(float(T[i, 0]), float(n[j]), MEASURED_LOW, gear)
            assert e.shape == () and t.shape == () and r.shape == ()
            assert eta[i, j] == e and tq[i, j] == t and rpm[i, j] == r


def test_low_gear_ratio_broadcasts_too():
    lo = np.array([MEASURED_LOW, 1.35])
    eta, tq, rpm = auxiliary_box(0.5, 1500.0, lo, "low")
    assert eta.shape == (2,)
    assert eta[1] == auxiliary_box(0.5, 1500.0, 1.35, "low")[0]
    np.testing.assert_allclose(rpm, 1500.0 / lo)  # RPM_O_aux = RPM_C_aux/G_L_aux


def test_large_inputs_in_blocks_equal_one_block(monkeypatch):
    rng = np.random.default_rng(1)
    T = rng.uniform(0, 1, (7, 13))
    n = rng.uniform(0, 4000, (7, 13))
    lo = rng.choice([MEASURED_LOW, 1.35], (7, 13))
    whole = [auxiliary_box(T, n, lo, g) for g in ("low", "high")]
    monkeypatch.setattr(box, "_CHUNK", 10)
    blocks = [auxiliary_box(T, n, lo, g) for g in ("low", "high")]
    for a, b in zip(whole, blocks):
        for x, y in zip(a, b):
            assert x.shape == (7, 13)
            np.testing.assert_array_equal(x, y)


def test_output_speed_and_ratio():
    _, _, rpm_low = auxiliary_box(0.5, 3000.0, MEASURED_LOW, "low")
    _, _, rpm_high = auxiliary_box(0.5, 3000.0, MEASURED_LOW, 2)
    assert rpm_low == pytest.approx(3000.0 / MEASURED_LOW, rel=1e-14)
    assert rpm_high == 3000.0


def test_floor_zero_torque_and_high_gear_standstill():
    # torque 0: the losses exceed the input, eta -> NaN -> 0 (B.6), torque -> 0
    for gear in ("low", "high"):
        eta, tq, _ = auxiliary_box(0.0, [0.0, 1000.0], MEASURED_LOW, gear)
        np.testing.assert_array_equal(eta, 0.0)
        np.testing.assert_array_equal(tq, 0.0)
    # high gear at 0 rpm: unloaded counter-shaft bearings give LF = 0/0 and a NaN loss
    eta, tq, _ = auxiliary_box([0.25, 1.0], 0.0, MEASURED_LOW, "high")
    np.testing.assert_array_equal(eta, 0.0)
    eta, _, _ = auxiliary_box([0.25, 1.0], 1000.0, MEASURED_LOW, "high")
    assert np.all((eta > 0.99) & (eta < 1.0))


def test_efficiencies_in_range_on_a_grid():
    T, n = np.meshgrid(np.linspace(0.05, 1, 20), np.linspace(0, 4000, 21))
    for lo in (MEASURED_LOW, 1.35):
        for gear in ("low", "high"):
            eta, _, _ = auxiliary_box(T, n, lo, gear)
            assert np.all((eta >= 0) & (eta < 1))


@pytest.mark.parametrize("bad", ["medium", 3, 0, None, True])
def test_unknown_gear(bad):
    with pytest.raises(InputError):
        auxiliary_box(0.5, 1000.0, MEASURED_LOW, bad)


# --------------------------------------------------------------------------------------------
# geometry data
# --------------------------------------------------------------------------------------------

def test_shipped_geometry_file():
    g = load_geometry()
    assert set(g) == set(box.GEOMETRY_KEYS)
    assert g["peak_torque"] == 5794.088
    assert g["initial_driven_teeth"] / g["initial_drive_teeth"] == 43 / 34
    assert g["low_driven_teeth"] / g["low_drive_teeth"] == 62 / 16
    assert g["centre_distance"] == 149.5044


def test_geometry_override_and_errors(tmp_path):
    base = auxiliary_box(0.5, 1500.0, MEASURED_LOW, "low")[0]
    same = auxiliary_box(0.5, 1500.0, MEASURED_LOW, "low", geometry={"peak_torque": 5794.088})[0]
    assert same == base
    # friction coefficient 0 -> both meshes lossless -> a higher efficiency
    lossless = auxiliary_box(0.5, 1500.0, MEASURED_LOW, "low",
                             geometry={"mesh_friction_coefficient": {"value": 0.0}})[0]
    assert lossless > base
    with pytest.raises(InputError, match="unknown two-speed box quantity"):
        auxiliary_box(0.5, 1500.0, MEASURED_LOW, "low", geometry={"peak_torq": 1.0})
    bad = tmp_path / "box.toml"
    bad.write_text('[peak_torque]\nvalue = 1.0\n')
    with pytest.raises(InputError, match="missing"):
        load_geometry(bad)
