"""``fleetrun cycles``: list the shipped drive cycles, or describe cycles and cycle CSVs.

    fleetrun cycles                      one shipped name per line (UDDS, HWFET, US06, NYCC,
                                         HD-UDDS first)
    fleetrun cycles --details            a table: name, duration [s], distance [mi],
                                         max and mean speed [mph] (mean includes stops)
    fleetrun cycles my_route.csv US06    the same table for the named cycles / CSV files
                                         (validates the files; a bad one gives Error: ...)
"""
from __future__ import annotations

import click

from fleetrun.cycles import cycle_summary, load_cycle, shipped_cycles

COLUMNS = (
    ("name", "name", "{}"),
    ("duration_s", "duration_s", "{:.0f}"),
    ("distance_mi", "distance_mi", "{:.3f}"),
    ("max_speed_mph", "max_speed_mph", "{:.1f}"),
    ("mean_speed_mph", "mean_speed_mph", "{:.2f}"),
)


def _table(rows: list[dict], fmt: str) -> str:
    header = [h for h, _, _ in COLUMNS]
    cells = [[f.format(r[k]) for _, k, f in COLUMNS] for r in rows]
    if fmt == "csv":
        return "\n".join(",".join(line) for line in [header] + cells)
    widths = [max(len(x) for x in col) for col in zip(header, *cells)]
    lines = []
    for i, line in enumerate([header] + cells):
        lines.append("  ".join(
            (x.ljust(w) if j == 0 else x.rjust(w)) for j, (x, w) in enumerate(zip(line, widths))
        ).rstrip())
    return "\n".join(lines)


@click.command("cycles")
@click.argument("cycles", nargs=-1, metavar="[NAME_OR_CSV]...")
@click.option("--details", is_flag=True,
              help="Print a table: duration [s], distance [mi], max and mean speed [mph].")
@click.option("--format", "fmt", type=click.Choice(["table", "csv"]), default="table",
              show_default=True, help="Layout of the --details table.")
@click.option("--cycle", "cycle_options", multiple=True, metavar="NAME_OR_CSV",
              help="A cycle to describe, as `simulate --cycle` takes it (same as the argument).")
def command(cycles, details, fmt, cycle_options):
    """List the shipped drive cycles (one name per line), or describe cycles.

    With NAME_OR_CSV arguments (shipped names or CSV files with time_s, one speed column and
    optional grade_pct) each is loaded and validated and its details are printed.
    """
    cycles = tuple(cycles) + tuple(cycle_options)
    if not cycles and not details:
        for name in shipped_cycles():
            click.echo(name)
        return
    names = list(cycles) if cycles else shipped_cycles()
    rows = [cycle_summary(load_cycle(n)) for n in names]
    click.echo(_table(rows, fmt))
