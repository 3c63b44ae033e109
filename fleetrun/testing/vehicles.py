"""Example vehicles of the simulation tests and benchmark (one per drivetrain family)."""
from fleetrun.vehicle import VehicleSpec


def _v(**kw):
    base = dict(vehicle_class="test", count=1, annual_miles=10000.0)
    base.update(kw)
    return VehicleSpec(**base)


# Ford F-150 of thesis Table 7.1 (coastdown, tyre, peak torque) with a 4-speed automatic
F150 = _v(vehicle_id="f150", duty_class="LD", configuration="LD_RWD", fuel="gasoline",
          peak_engine_torque_Nm=400.0, transmission="automatic", transmission_gear_ratios=(2.84, 1.55, 1.0, 0.7),
          final_drive_ratio=3.55, test_weight_kg=2268.0, coastdown_A_lbf=21.8, coastdown_B_lbf_per_mph=0.9315,
          coastdown_C_lbf_per_mph2=0.03266, tire_size="P235/75R15")
# 2018 Camry (inputs/dyno sidecar values)
CAMRY = _v(vehicle_id="camry", duty_class="LD", configuration="LD_FWD", fuel="gasoline",
           peak_engine_torque_Nm=249.5, transmission="automatic",
           transmission_gear_ratios=(5.519, 3.184, 2.050, 1.492, 1.235, 1.000, 0.801, 0.673),
           final_drive_ratio=2.8, test_weight_kg=1644.27, coastdown_A_lbf=26.509, coastdown_B_lbf_per_mph=0.19851,
           coastdown_C_lbf_per_mph2=0.016476, tire_size="235/45R18", rated_power_kW=151.4, rated_speed_rpm=6600.0,
           engine_displacement_L=2.487)
# Honda Civic of Table 7.1, 5-speed manual
CIVIC = _v(vehicle_id="civic", duty_class="LD", configuration="LD_FWD", fuel="gasoline",
           peak_engine_torque_Nm=157.3, transmission="manual", transmission_gear_ratios=(3.25, 1.9, 1.25, 0.92, 0.73),
           final_drive_ratio=4.06, test_weight_kg=1134.0, coastdown_A_lbf=15.4, coastdown_B_lbf_per_mph=0.1384,
           coastdown_C_lbf_per_mph2=0.01960, tire_size="P175/70R13")
# AWD crossover
AWD = _v(vehicle_id="awd", duty_class="LD", configuration="LD_AWD", fuel="gasoline", peak_engine_torque_Nm=240.0,
         transmission="automatic", transmission_gear_ratios=(4.6, 2.7, 1.8, 1.3, 1.0, 0.8), final_drive_ratio=3.6,
         test_weight_kg=1800.0, coastdown_A_lbf=30.0, coastdown_B_lbf_per_mph=0.3, coastdown_C_lbf_per_mph2=0.022,
         tire_size="225/65R17")
# Class 8 tractor-trailer, 10-speed manual, single drive axle (~36 t combination)
HD_TRUCK = _v(vehicle_id="class8", duty_class="HD", configuration="HD_RWD", fuel="diesel",
              peak_engine_torque_Nm=2500.0, transmission="manual",
              transmission_gear_ratios=(12.8, 9.25, 6.76, 4.99, 3.68, 2.44, 1.76, 1.3, 1.0, 0.78),
              final_drive_ratio=3.55, test_weight_kg=36000.0, coastdown_A_lbf=340.0, coastdown_B_lbf_per_mph=2.0,
              coastdown_C_lbf_per_mph2=0.14, tire_size="295/75R22.5", rated_power_kW=336.0, rated_speed_rpm=1800.0)
# Medium truck with a two-speed (dual) axle, automatic
HD_DUAL = _v(vehicle_id="dual", duty_class="HD", configuration="HD_DUAL", fuel="diesel", peak_engine_torque_Nm=900.0,
             transmission="automatic", transmission_gear_ratios=(3.1, 1.81, 1.41, 1.0, 0.71), final_drive_ratio=5.29,
             low_gear_ratio=1.36, test_weight_kg=12000.0, coastdown_A_lbf=150.0, coastdown_B_lbf_per_mph=1.0,
             coastdown_C_lbf_per_mph2=0.08, tire_size="11R22.5")

ALL = [F150, CAMRY, CIVIC, AWD, HD_TRUCK, HD_DUAL]
