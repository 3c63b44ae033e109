"""An independent, literal scalar transcription of thesis Appendix B.1, B.2, B.4, B.6, B.7.

Written line by line from the printed MATLAB (not from models/*.toml), with MATLAB's
semantics: IEEE division (x/0 = inf, 0/0 = NaN), B.6 applied after every stage. Used by the
tests to check fleetrun's data-driven chains at gear ratios, torques and speeds that the
shared reference grid does not contain. Slow (pure Python), so only for test-sized samples.
"""
import math

NAN = float("nan")


def _div(a, b):
    if b == 0:
        if a == 0 or a != a:
            return NAN
        return math.copysign(math.inf, a) * (1 if math.copysign(1, b) > 0 else -1)
    return a / b


def _floor(eta, torque):  # B.6 EtaNTorqCorrect(..., true)
    if eta < 0:
        return NAN, NAN
    return eta, torque


def _final(eta, torque):  # B.6 EtaNTorqCorrect(..., false)
    if eta != eta:
        return 0.0, 0.0
    return eta, torque


def walthers(index):  # B.7
    T = 70 + 273.15
    cte = 7e-4
    if index == 0:
        b, s = 1.458e-6, 110.4
        mu = b * T ** 0.5 / (1 + s / T)
        rho = 1.2250 * (1 - cte * (T - 288.2)) ** -1
        return rho, mu, mu / rho
    density = [854, 859, 887][index - 1]
    v1 = [7.2, 15.9, 15][index - 1]
    v2 = [35, 120, 139][index - 1]
    T1, T2 = 373.15, 313.15
    y1 = math.log10(math.log10(v1 + 0.8))
    y2 = math.log10(math.log10(v2 + 0.8))
    x1, x2 = math.log10(T1), math.log10(T2)
    B = (y1 - y2) / (x1 - x2)
    A = y1 - B * x1
    nu = (10 ** (10 ** (A + B * math.log10(T))) - 0.8) * 1e-6
    rho = density * (1 + cte * (T - 288.2)) ** -1
    return rho, nu * rho, nu


def _bearing_moment(P, d, D, rpm, nu):
    mu, f_L, f_1, f_2 = 0.0018, 8, 20, 25
    d_m = 0.5 * (d + D)
    M_P = 5e-4 * mu * P * d
    if 2 * math.pi / 60 * rpm * nu > 2000:
        M_L = 1e-10 * f_L * (2 * math.pi / 60 * rpm * nu) ** (2 / 3) * d_m ** 3
    else:
        M_L = 1.6e-8 * f_L * d_m ** 3
    M_S = 1e-3 * (((d + D) / f_1) ** 2 + f_2)
    return M_P + M_L + M_S


def eff_diff_trans(scaled_torque, speed, gr):  # B.1
    eff = 1.0
    cap = 285 * 4.69 * 3
    torque = scaled_torque * cap
    eqG = 2.6521739130434782608695652173913
    rho_air, mu_air, nu_air = walthers(0)
    R_p_pinion = 0.12794339139344262295081967213115
    L_fw = 0.034925
    OD_D = 0.259855327868852459016393442623
    rho_oil, mu_oil, nu_oil = walthers(1)
    nu = nu_oil
    C = 0.46727151639344262295081967213115
    alpha = 0.34906585039886591538473815369772
    G = gr
    if gr < eqG:
        OD_D = OD_D * eqG / gr
        R_p_pinion = R_p_pinion * eqG / gr
        C = C * (1 + 1 / gr) / (1 + 1 / eqG)
    else:
        C = C * (1 + eqG ** 2 / gr) / (1 + eqG)
    mu_f_gp, X, C_E = 0.04, 0, 0.7
    tp = 1.069e-4 * C_E * (1 + 2.3 * L_fw / R_p_pinion) * speed ** 1.85 * OD_D ** 4.7 * (
        X * (rho_oil * nu_oil ** .15) + (1 - X) * (rho_air * nu_air ** .15))
    e = 1 - _div(tp, torque); torque *= e; eff *= e; eff, torque = _floor(eff, torque)
    eps = 1.1337
    eg = 1 - ((mu_f_gp / (2 * C / (1 + G) * math.cos(alpha))) * abs(1 - 1 / G) * (C * math.sin(alpha) / (1 + G))
              * (1 + G ** 2) / abs(1 - G) * (1 - eps + eps ** 2))
    torque = torque * G * eg; speed = speed / G; eff *= eg; eff, torque = _floor(eff, torque)
    R_i_gear = 0.06985
    if gr > eqG:
        R_i_gear = R_i_gear * gr / eqG
    tg = 1.069e-4 * C_E * (1 + 2.3 * L_fw / R_p_pinion / G) * speed ** 1.85 * (
        (OD_D * G) ** 4.7 - (2 * R_i_gear * G) ** 4.7) * (X * (rho_oil * nu_oil ** .15) + (1 - X) * (rho_air * nu_air ** .15))
    e = 1 - _div(tg, torque); torque *= e; eff *= e; eff, torque = _floor(eff, torque)
    r, R = 0.06985, 0.0762
    if gr > eqG:
        r = r * gr / eqG; R = R * gr / eqG
    e = 1 - _div(4 * math.pi ** 2 / 45 * mu_air * speed * r ** 4 / (R - r), torque)
    eff *= e; torque = torque * e / 2; eff, torque = _floor(eff, torque)
    P = torque * 0.339328125 / math.cos(math.pi / 9) / 2
    M = _bearing_moment(P, 68.150711090682830570592951793237, 80.850711090682830570592951793237, speed, nu)
    e = 1 - _div(M, torque); eff *= e; torque *= e; eff, torque = _floor(eff, torque)
    omega = 2 * math.pi / 60 * speed
    D = 0.047625; a = (0.060325 - D) / 2; L = 0.0254
    e = 1 - _div(math.pi / 4 * mu_air * D ** 3 * L / a * omega, torque); eff *= e; torque *= e; eff, torque = _floor(eff, torque)
    r_shaft = 0.01465419138518626304091997251250245
    e = 1 - _div(2 * math.pi * r_shaft ** 2 * (50 + 170 * 0.5), torque); torque *= e; eff *= e; eff, torque = _floor(eff, torque)
    D = 0.029308382770372526081839945025049; a = (0.054708382770372526081839945025049 - D) / 2; L = 0.3048
    e = 1 - _div(math.pi / 4 * mu_air * D ** 3 * L / a * omega, torque); eff *= e; torque *= e; eff, torque = _floor(eff, torque)
    torque = torque / cap / G * 2
    return _final(eff, torque)


def _rear(torque, rpm, g_r, heavy):  # B.2 (heavy=False) and B.4 (heavy=True)
    eta = 1.0
    k = 1.27576 * 41 / 12 / 3.9
    peak = 32000 if heavy else 6266.72614
    torque = torque * peak
    _, mu_air, _ = walthers(0)
    _, mu_oil, _ = walthers(3)
    if heavy:
        r_o_p = (1.9375 + 2.84375) / 4 * 1.27576 * 41 / 12 / 3.9
        r_p_p = r_o_p - 0.1875 * 1.27576 * 41 / 12 / 3.9
        G = 3.90
    else:
        r_o_p = (1.9375 + 2.84375) / 4
        r_p_p = r_o_p - 0.1875
        G = 41 / 12
    phi_n = 20 * math.pi / 180
    if g_r < G:
        r_o_p = r_o_p * G / g_r; r_p_p = r_p_p * G / g_r
    r_shaft = 0.028575
    e = 1 - _div(2 * math.pi * r_shaft ** 2 * (50 + 170 * 1), torque); torque *= e; eta *= e; eta, torque = _floor(eta, torque)
    nu = 36.6e-6
    P = torque * r_p_p / math.cos(phi_n) / 1
    d = r_shaft * 2e3; D = 81 / 68 * d
    e = 1 - _div(_bearing_moment(P, d, D, rpm, nu), torque); eta *= e; torque *= e; eta, torque = _floor(eta, torque)
    omega = 2 * math.pi / 60 * rpm
    d = d / 1e3; D = D / 1e3; a = (D - d) / 2; L = 0.1016; mu = mu_air
    e = 1 - _div(math.pi / 4 * mu * d ** 3 * L / a * omega, torque); eta *= e; torque *= e; eta, torque = _floor(eta, torque)
    if heavy:
        l_fw_p = 2.9375 * 1.27576 * 41 / 12 / 3.9; l_fw_g = 1.46875 * 1.27576
    else:
        l_fw_p = 2.9375; l_fw_g = 1.46875
    t_p = 12
    if g_r < G:
        l_fw_p = l_fw_p * G / g_r; t_p = t_p * G / g_r
    elif g_r > G:
        l_fw_g = l_fw_g * g_r / G
    psi_p = math.acos(1.75 / 2.9375); psi_g = math.acos(1.3125 / 1.46875)
    L_fw = l_fw_p; psi = psi_p
    R_f = 7.7782 - 0.1682 * t_p / (2 * r_p_p)
    X = 0 if heavy else 0.5
    tq = 15 / 0.746 * (X * mu_oil + (1 - X) * mu_air) / mu_air * (rpm / 1000) ** 2 / (1000 / 60 * 2 * math.pi) * (
        2 * r_p_p / 100) ** 4 * (5 * L_fw / 100 * (1 + R_f / math.sqrt(math.tan(psi))) + 2 * r_p_p / 100)
    e = 1 - _div(tq * 745.7, torque); eta *= e; torque *= e; eta, torque = _floor(eta, torque)
    dx_dt = rpm * math.sqrt((r_o_p - r_p_p) ** 2 + (l_fw_p - l_fw_g) ** 2 / 4) / 12 * t_p
    f = 0.8 / (dx_dt + 100) ** 0.5
    eg = (math.cos(phi_n) + f * math.tan(psi_g)) / (math.cos(phi_n) + f * math.tan(psi_p))
    eta *= eg; torque = torque * g_r * eg; rpm = rpm / g_r; eta, torque = _floor(eta, torque)
    psi = psi_g
    r_p_g = r_p_p * g_r
    r_i_g = 16.25 / 2 / math.pi * (1.27576 if heavy else 1)
    X = 0.03 if heavy else 0.2
    tq = 15 / 0.746 * (X * mu_oil + (1 - X) * mu_air) / mu_air * (rpm / 1000) ** 2 / (1000 / 60 * 2 * math.pi) * (
        2 * r_p_g / 100) ** 4 * (5 * L_fw / 100 * (1 + R_f / math.sqrt(math.tan(psi))) + 2 * (r_p_g ** 5 - r_i_g ** 5) / r_p_g ** 4 / 100)
    e = 1 - _div(tq * 745.7, torque); eta *= e; torque *= e; eta, torque = _floor(eta, torque)
    X = 0 if heavy else 0.1
    r = r_i_g * 0.0254; R = r + 0.0254
    if not heavy and g_r > G:
        r = r * g_r / G; R = R * g_r / G
    e = 1 - _div(4 * math.pi ** 2 / 45 * (X * mu_oil + (1 - X) * mu_air) * rpm * r ** 4 / (R - r), torque)
    eta *= e; torque = torque * e / 2; eta, torque = _floor(eta, torque)
    omega = 2 * math.pi / 60 * rpm
    d = 1.25 * (1.27576 if heavy else 1) * 0.0254
    a = (2.5 * (1.27576 if heavy else 1) * .0254 - d) / 2
    L = 3 * 0.0254
    e = 1 - _div(math.pi / 4 * mu * D ** 3 * L / a * omega, torque); eta *= e; torque *= e; eta, torque = _floor(eta, torque)
    P = torque * r_p_g / math.cos(phi_n) / 2 * 2
    d = d * 1e3; D = D * 1e3
    e = 1 - _div(_bearing_moment(P, d, D, rpm, nu), torque); eta *= e; torque *= e; eta, torque = _floor(eta, torque)
    r_shaft = d / 2e3
    e = 1 - _div(2 * math.pi * r_shaft ** 2 * (50 + 170 * 1), torque); torque *= e; eta *= e; eta, torque = _floor(eta, torque)
    torque = torque / peak / g_r * 2
    return _final(eta, torque)


def eff_diff_rear_ld(torque, rpm, g_r):
    return _rear(torque, rpm, g_r, heavy=False)


def eff_diff_rear_hd(torque, rpm, g_r):
    return _rear(torque, rpm, g_r, heavy=True)


def configuration_efficiency(config, tf, rpm, g):
    """Eqs 5.23-5.29 for the configurations without the two-speed box."""
    if config == "LD_FWD":
        return eff_diff_trans(tf, rpm, g)[0]
    if config == "LD_RWD":
        return eff_diff_rear_ld(tf, rpm, g)[0]
    if config == "LD_4WD":  # B.3
        return eff_diff_rear_ld(tf * 0.99, rpm, g)[0] * 0.99
    if config == "LD_AWD":
        return eff_diff_trans(tf, rpm, g)[0] * eff_diff_rear_ld(tf, rpm, g)[0]
    if config in ("HD_RWD", "HD_TAG"):
        return eff_diff_rear_hd(tf, rpm, g)[0]
    if config == "HD_TANDEM":
        return eff_diff_trans(tf, rpm, g)[0] * eff_diff_rear_hd(tf, rpm, g)[0]
    raise KeyError(config)
