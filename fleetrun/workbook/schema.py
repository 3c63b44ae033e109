"""The fleet workbook's sheets and columns (docs/interface.md, "Fleet workbook").

One list of :class:`Column` per sheet is shared by the reader (what to check), the template
writer (headers, drop-downs, notes) and the docs, so the three cannot drift apart.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

from fleetrun.differential import configuration_ids, dual_configuration_ids

VEHICLES_SHEET = "Vehicles"
SCENARIOS_SHEET = "Scenarios"
REGISTRATIONS_SHEET = "Registrations"

CONFIGURATIONS = tuple(configuration_ids())              # models/configurations.toml
DUAL_CONFIGURATIONS = tuple(dual_configuration_ids())
DUTY_CLASSES = ("LD", "MD", "HD")
FUELS = ("gasoline", "diesel", "electric")
# FHWA classes of the Registrations sheet; "truck" is MV-1's all trucks (split by documented shares)
FHWA_CLASSES = ("automobile", "light_truck", "single_unit_truck", "combination_truck", "bus", "motorcycle")
REGISTRATION_CLASSES = FHWA_CLASSES + ("truck",)
ONROAD_CHOICES = ("epa_label", "none")   # or a positive factor
# The template's example rows carry this id prefix; `validate` warns while one is left in.
EXAMPLE_PREFIX = "EXAMPLE-"
TRANSMISSIONS = ("automatic", "manual")
GEARBOX_TYPES = ("automatic", "automated_manual", "cvt", "manual")
YES_NO = ("yes", "no")


@dataclass(frozen=True, eq=False)   # hashed by identity: one object per column
class Column:
    """One column of a sheet. A number's physical range is ``minimum``..``maximum``
    (``strictly_positive``: above 0): outside it, ``validate`` and ``run`` refuse the cell.
    ``plausible`` is the usual range (a (low, high) pair, or per duty class a dict of them):
    outside it, a warning. Adding a column with its range is one line here; the reader, the
    template's Instructions sheet and docs/workbook.md all take it from this list."""
    name: str
    kind: str                 # "text", "number", "choice", "ratios", "cycle_mix", "integer", "onroad",
                              # "schedule", "class_shares"
    required: bool
    note: str
    choices: tuple[str, ...] = ()
    minimum: float | None = None         # values below are errors (inclusive unless strict)
    maximum: float | None = None         # values above are errors
    strictly_positive: bool = False
    example: tuple = ()                  # two example values for the template
    plausible: tuple | dict | None = None   # warn outside: (low, high) or {duty_class: (low, high)}

    @property
    def numeric(self) -> bool:
        """Whether the column holds numbers (for ratios and the on-road factor: each number)."""
        return self.kind in ("number", "integer", "ratios", "onroad", "schedule")

    def range_text(self) -> str:
        """The physical range as the template and the docs show it, e.g. ``> 0 to 10,000``."""
        if not self.numeric:
            return ""
        low = "> 0" if self.strictly_positive and not self.minimum else _number_text(self.minimum)
        return f"{low} to {_number_text(self.maximum)}"


def _number_text(value) -> str:
    if value is None:
        return "any"
    return f"{value:,.0f}" if float(value).is_integer() and abs(value) >= 10_000 else f"{value:g}"


VEHICLE_COLUMNS: tuple[Column, ...] = (
    Column("vehicle_id", "text", True, "unique id of this vehicle type",
           example=(EXAMPLE_PREFIX + "LD-CAR-01", EXAMPLE_PREFIX + "HD-TRACTOR-01")),
    Column("vehicle_class", "text", True, "label the reports aggregate by", example=("Passenger car", "Class 8 tractor")),
    Column("duty_class", "choice", True, "LD, MD or HD", choices=DUTY_CLASSES, example=("LD", "HD")),
    Column("configuration", "choice", True, "differential configuration", choices=CONFIGURATIONS,
           example=("LD_FWD", "HD_TANDEM")),
    Column("count", "number", True, "vehicles of this type", minimum=0, maximum=1e8, example=(125000, 4200)),
    Column("annual_miles", "number", True, "miles per vehicle per year", minimum=0, maximum=500_000,
           example=(11500, 85000),
           plausible={"LD": (500, 50000), "MD": (1000, 100000), "HD": (1000, 200000)}),
    Column("fuel", "choice", True, "gasoline, diesel or electric", choices=FUELS, example=("gasoline", "diesel")),
    Column("peak_engine_torque_Nm", "number", True, "peak engine torque [N m]", minimum=10, maximum=10_000,
           example=(250, 2500),
           plausible={"LD": (50, 1100), "MD": (200, 1600), "HD": (500, 3500)}),
    Column("transmission", "choice", True, "automatic or manual", choices=TRANSMISSIONS,
           example=("automatic", "manual")),
    Column("transmission_gear_ratios", "ratios", True, "comma list, first gear first (each ratio "
           "0.2 to 30, at most 20 gears)", minimum=0.2, maximum=30,
           example=("4.62,3.04,2.06,1.66,1.26,1.00,0.85,0.69",
                    "12.8,9.25,6.76,4.9,3.58,2.61,1.89,1.38,1.00,0.73")),
    Column("final_drive_ratio", "number", True, "differential gear ratio", minimum=1.2, maximum=12.0,
           example=(3.21, 3.55), plausible={"LD": (2.0, 6.0), "MD": (2.5, 8.0), "HD": (2.0, 8.0)}),
    Column("test_weight_kg", "number", True, "test (loaded) weight [kg]", minimum=200, maximum=100_000,
           example=(1588, 29000),
           plausible={"LD": (600, 4500), "MD": (3500, 15000), "HD": (6000, 40000)}),
    Column("coastdown_A_lbf", "number", True, "EPA target coefficient A [lbf]", minimum=0, maximum=2000,
           example=(29.5, 240.0)),
    Column("coastdown_B_lbf_per_mph", "number", True, "EPA target coefficient B [lbf/mph]", minimum=-20,
           maximum=50, example=(0.115, 1.5)),
    Column("coastdown_C_lbf_per_mph2", "number", True, "EPA target coefficient C [lbf/mph^2]", minimum=0,
           maximum=5, example=(0.0185, 0.12)),
    Column("tire_size", "text", True, "e.g. P235/75R15 or 295/75R22.5", example=("P215/55R17", "295/75R22.5")),
    Column("torque_converter_ratio", "number", False, "default 3.0 automatic, 1.0 manual", minimum=1.0,
           maximum=5.0),
    Column("kim_torque_scale_Nm", "number", False, "overrides peak x converter x first gear", minimum=10,
           maximum=2_000_000),
    Column("low_gear_ratio", "number", False, "two-speed (dual) axles only: low-range multiplier, e.g. 1.35 (low = final drive x this)",
           minimum=1.0, maximum=15.0),
    Column("rated_power_kW", "number", False, "rated engine power [kW]", minimum=10, maximum=2000,
           example=(150, 336)),
    Column("rated_speed_rpm", "number", False, "rated engine speed [rpm]", minimum=1000, maximum=12_000,
           example=(6100, 1800)),
    Column("engine_displacement_L", "number", False, "engine displacement [L]", minimum=0.5, maximum=30,
           example=(2.5, 12.8)),
    Column("lubricant", "text", False, "axle lubricant name (default: the configuration's)"),
    # Optional identification and powertrain details (`fleetrun import-epa` fills them from
    # the EPA Test Car List; a row without them runs on defaults).
    Column("manufacturer", "text", False, "vehicle manufacturer (identification)"),
    Column("make", "text", False, "make (identification)"),
    Column("model", "text", False, "model (identification)"),
    Column("model_year", "integer", False, "model year (identification)", minimum=1900, maximum=2200),
    Column("gearbox_type", "choice", False, "automatic (torque converter), automated_manual, cvt or manual",
           choices=GEARBOX_TYPES),
    Column("converter_lockup", "choice", False, "torque-converter lock-up: yes or no", choices=YES_NO),
    Column("cylinders", "integer", False, "number of engine cylinders", minimum=1, maximum=24),
    Column("nv_ratio_rpm_per_mph", "number", False, "engine rpm per mph in top gear (EPA N/V)",
           minimum=5, maximum=300),
    # Light-duty fuel economy (docs/simulation.md "Technology"): technology classes and one measured number
    Column("technology", "text", False, "comma list: start_stop, mild_hybrid_48v, p2_hybrid, atkinson, miller, "
           "cylinder_deactivation, turbo"),
    Column("measured_ftp_mpg", "number", False, "this vehicle's measured FTP composite [mpg, unadjusted]: "
           "calibrates its efficiency", minimum=3, maximum=200),
    Column("label_combined_mpg", "number", False, "its EPA label combined [mpg], used when no measured FTP",
           minimum=3, maximum=200),
    Column("label_group", "text", False, "rows that share one EPA label (its model type's configurations): "
           "one fuel scale for them all"),
    Column("label_city_mpg", "number", False, "its EPA label city [mpg]; with label_highway_mpg, used when no "
           "measured FTP", minimum=3, maximum=200),
    Column("label_highway_mpg", "number", False, "its EPA label highway [mpg]; with label_city_mpg, used when "
           "no measured FTP", minimum=3, maximum=200),
)

# cycle_mix_MD / cycle_mix_HD go beyond docs/interface.md: heavy trucks cannot follow light-duty
# cycles such as US06, so a scenario may give them their own mix.
SCENARIO_COLUMNS: tuple[Column, ...] = (
    Column("scenario_id", "text", True, "unique id of this scenario",
           example=(EXAMPLE_PREFIX + "baseline", EXAMPLE_PREFIX + "hot_summer")),
    Column("description", "text", False, "free text for the reports",
           example=("Average year, mixed driving", "Heat wave: 38 C ambient")),
    Column("ambient_temp_C", "number", True, "ambient temperature [C]", minimum=-50, maximum=60,
           example=(20, 38), plausible=(-40.0, 50.0)),
    Column("cycle_mix", "cycle_mix", True, "CYCLE:share list, shares of annual miles, sum 1; or default "
           "(each duty class's documented mix)",
           example=("UDDS:0.55,HWFET:0.45", "UDDS:0.5,HWFET:0.4,US06:0.1")),
    Column("budget_years", "integer", True, "years forecast (2 = a biennium)", minimum=1, maximum=50,
           example=(2, 2), plausible=(1, 10)),
    Column("vmt_growth_pct_per_year", "number", True, "growth of annual miles [% per year]", minimum=-50,
           maximum=50, example=(1.0, 1.0), plausible=(-10.0, 10.0)),
    Column("state_tax_gasoline_usd_per_gal", "number", True, "state gasoline tax [$/gal]", minimum=0,
           maximum=20, example=(0.20, 0.20), plausible=(0.0, 1.0)),
    Column("state_tax_diesel_usd_per_gal", "number", True, "state diesel tax [$/gal]", minimum=0,
           maximum=20, example=(0.20, 0.20), plausible=(0.0, 1.0)),
    Column("federal_tax_gasoline_usd_per_gal", "number", True, "federal gasoline tax [$/gal]", minimum=0,
           maximum=20, example=(0.184, 0.184), plausible=(0.0, 1.0)),
    Column("federal_tax_diesel_usd_per_gal", "number", True, "federal diesel tax [$/gal]", minimum=0,
           maximum=20, example=(0.244, 0.244), plausible=(0.0, 1.0)),
    Column("cycle_mix_MD", "cycle_mix", False, "MD vehicles' cycle mix (empty: cycle_mix)",
           example=("HD-UDDS:0.5,UDDS:0.2,HWFET:0.3", "HD-UDDS:0.5,UDDS:0.2,HWFET:0.3")),
    Column("cycle_mix_HD", "cycle_mix", False, "HD vehicles' cycle mix (empty: cycle_mix)",
           example=("HD-UDDS:0.6,HWFET:0.4", "HD-UDDS:0.6,HWFET:0.4")),
    # Budget columns (docs/interface.md, optional): fiscal years, on-road fuel, calibration, EV fee.
    Column("first_fiscal_year", "integer", False, "fiscal year of budget year 1, e.g. 2027 "
           "(empty: years numbered 1, 2, ...)", minimum=1900, maximum=2200, example=(2027, 2027),
           plausible=(1990, 2100)),
    Column("onroad_adjustment", "onroad", False, "cycle fuel -> on-road fuel: epa_label (default; "
           "EPA's label formulas), none, or a factor such as 1.2", minimum=0.5, maximum=3.0),
    Column("observed_base_gallons_gasoline", "number", False, "taxable gasoline gallons collected "
           "in the first fiscal year (for calibration)", strictly_positive=True, maximum=1e12),
    Column("observed_base_gallons_diesel", "number", False, "taxable diesel gallons collected "
           "in the first fiscal year (for calibration)", strictly_positive=True, maximum=1e12),
    Column("calibrate_to_observed", "choice", False, "yes: scale each fuel's forecast so the first "
           "fiscal year equals the observed gallons (default no)", choices=YES_NO),
    Column("ev_fee_usd_per_vehicle_year", "number", False, "annual fee per electric vehicle [$] "
           "(default 0)", minimum=0, maximum=100_000, plausible=(0.0, 1000.0)),
    # Drivers (forecast issue, docs/budget.md): fiscal periods, fuel price and its response, tax per year.
    Column("fiscal_year_start_month", "integer", False, "first month of the fiscal year, 1-12 "
           "(7 = July to June, the default; 9 = September to August)", minimum=1, maximum=12),
    Column("fuel_price_gasoline_usd_per_gal", "schedule", False, "retail gasoline price [$/gal]: one number, "
           "or per fiscal year 2027:3.40,2028:3.55 (gallons respond by the price elasticity)",
           minimum=0.01, maximum=50),
    Column("fuel_price_diesel_usd_per_gal", "schedule", False, "retail diesel price [$/gal]: one number "
           "or per fiscal year", minimum=0.01, maximum=50),
    Column("price_elasticity_short_run", "number", False, "gallons per price, first year (default "
           "models/budget.toml)", minimum=-3, maximum=0),
    Column("price_elasticity_long_run", "number", False, "gallons per price, long run (default "
           "models/budget.toml)", minimum=-3, maximum=0),
    Column("state_tax_schedule_gasoline_usd_per_gal", "schedule", False, "state gasoline tax per fiscal year, "
           "2027:0.30,2028:0.31 (years not listed: the last listed year's rate)", minimum=0, maximum=20),
    Column("state_tax_schedule_diesel_usd_per_gal", "schedule", False, "state diesel tax per fiscal year",
           minimum=0, maximum=20),
    Column("state_tax_index_pct_per_year", "number", False, "state rates indexed: rate of year y = "
           "rate x (1 + i)^(y - 1) [% per year]", minimum=-50, maximum=50, plausible=(-5.0, 10.0)),
    # Registrations columns (docs/registrations.md)
    Column("base_year_vmt_million", "number", False, "the base fiscal year's vehicle-miles in millions "
           "(e.g. FHWA VM-2); all miles are scaled to it", strictly_positive=True, maximum=1e7,
           # usual: a county's fleet (100) to the nation's (3.3 million million miles, FHWA VM-1 2019);
           # below, VMT typed in billions (60 for 60,000) would shrink every mile 1,000 times
           plausible=(100.0, 4_000_000.0)),
    Column("base_year_vmt_share_pct", "class_shares", False, "percent of the base year's vehicle-miles "
           "driven by FHWA class, e.g. combination_truck:9.1, single_unit_truck:4.6, bus:0.6 (your state's "
           "VMT by vehicle type, FHWA VM-4 / HPMS); classes not listed share the rest (docs/registrations.md)"),
    Column("new_vehicle_mpg_change_pct_per_year", "number", False, "fuel-economy change of each new model "
           "year beyond the published trend [% per year] (empty: the trend's last ten years)",
           minimum=-20, maximum=20),
    # Per-class calibration (docs/budget.md): collections split into light and medium/heavy duty
    *[Column(f"observed_base_gallons_{fuel}_{group}", "number", False, f"taxable {fuel} gallons of "
             f"{label} rows in the first fiscal year (per-class calibration: give both _LD and _HD)",
             strictly_positive=True, maximum=1e12)
      for fuel in ("gasoline", "diesel") for group, label in (("LD", "light-duty"), ("HD", "medium- and heavy-duty"))],
)


# Registrations sheet (docs/registrations.md): the fleet as a registration office counts it.
REGISTRATION_COLUMNS: tuple[Column, ...] = (
    Column("vehicle_class", "choice", True, "FHWA class: automobile, light_truck, single_unit_truck, "
           "combination_truck, bus, motorcycle, or truck (MV-1 all trucks)", choices=REGISTRATION_CLASSES,
           example=("automobile", "truck")),
    Column("count", "number", True, "vehicles registered", minimum=0, maximum=1e9, example=(2_300_000, 3_000_000)),
    Column("model_year", "integer", False, "model year (empty: the class's default age distribution)",
           minimum=1900, maximum=2200),
    Column("fuel", "choice", False, "gasoline, diesel or electric (empty: the class's default split)",
           choices=FUELS),
    Column("make", "text", False, "make, matched to the EPA Test Car List (e.g. Toyota)"),
    Column("model", "text", False, "model, matched to the EPA Test Car List (e.g. Camry)"),
    Column("vehicle_id", "text", False, "a Vehicles row that represents these vehicles"),
    Column("annual_miles", "number", False, "miles per vehicle per year (empty: by class and age)",
           minimum=0, maximum=500_000),
)


def _renamed(columns, name: str, new_name: str, note: str) -> Column:
    return replace(next(c for c in columns if c.name == name), name=new_name, note=note, required=False)


# Keys of a differential-level diagnose sidecar (docs/interface.md, Recordings) with the ranges of
# the Vehicles and Scenarios columns they mean.
SIDECAR_COLUMNS: tuple[Column, ...] = (
    _renamed(VEHICLE_COLUMNS, "final_drive_ratio", "gear_ratio", "differential gear ratio"),
    _renamed(VEHICLE_COLUMNS, "peak_engine_torque_Nm", "peak_engine_torque_Nm", "peak engine torque [N m]"),
    _renamed(VEHICLE_COLUMNS, "torque_converter_ratio", "torque_converter_ratio", "3.0 automatic, 1.0 manual"),
    _renamed(VEHICLE_COLUMNS, "transmission_gear_ratios", "max_transmission_gear_ratio",
             "first (largest) transmission gear ratio"),
    _renamed(VEHICLE_COLUMNS, "low_gear_ratio", "low_gear_ratio", "two-speed axle low ratio"),
    _renamed(VEHICLE_COLUMNS, "lubricant", "lubricant", "axle lubricant name"),
    _renamed(SCENARIO_COLUMNS, "ambient_temp_C", "ambient_temp_C", "ambient temperature [C]"),
)

# Plausibility (warnings, not errors: analysts model unusual vehicles on purpose), as the
# columns above give it: Vehicles keyed by duty class, Scenarios by column; (low, high).
PLAUSIBLE_VEHICLE = {c.name: c.plausible for c in VEHICLE_COLUMNS if c.plausible}
PLAUSIBLE_SCENARIO = {c.name: c.plausible for c in SCENARIO_COLUMNS if c.plausible}


def columns_by_name(columns) -> dict[str, Column]:
    return {c.name: c for c in columns}
