"""What a numba-compiled kernel would cost every new process, before it computes anything.

    pip install numba
    python benchmarks/bench_numba_start.py [--rounds 5] [--fleet FLEET.xlsx]

Each line is a new Python process pinned to one CPU (``taskset`` where there is one), timed by
its CPU time (user + system, the figure of docs/benchmarks-run.md); the best of ``--rounds``:

- ``python + numpy``: the interpreter and numpy alone;
- ``+ import numba``;
- ``+ one cached @njit call``: a trivial ``@njit(cache=True)`` function, compiled into a
  temporary folder's ``__pycache__`` beforehand (warm cache), called once: numba's first
  dispatch loads its numpy implementations and probes for BLAS by importing scipy.linalg;
- ``scipy.linalg alone``: that import by itself, for the share of it.

With ``--fleet`` (e.g. the 7,600-row fleet of bench_end_to_end.py), ``fleetrun run FLEET``
plain and with the cached call first, alternating. The measurement and the decision it led to
are in docs/benchmarks-simulation.md ("A compiled kernel (numba), measured").
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PROBE = '''
import numpy as np
from numba import njit


@njit(cache=True)
def total(a):
    s = 0.0
    for x in a:
        s += x
    return s
'''
CASES = {
    "python + numpy": "import numpy",
    "+ import numba": "import numpy, numba",
    "+ one cached @njit call": "import numpy as np, probe; probe.total(np.ones(3))",
    "scipy.linalg alone (numpy + scipy.linalg)": "import numpy, scipy.linalg",
}


def pinned(command: list[str]) -> list[str]:
    return ["taskset", "-c", "0", *command] if shutil.which("taskset") else command


def cpu_seconds(command: list[str], env: dict) -> float:
    """User + system CPU seconds of one child process."""
    before = os.times()
    subprocess.run(pinned(command), env=env, check=True, capture_output=True, cwd=env.get("PWD"))
    after = os.times()
    return (after.children_user - before.children_user) + (after.children_system - before.children_system)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--fleet", type=Path, help="also time `fleetrun run FLEET` with and without the cached call")
    args = p.parse_args(argv)
    folder = Path(tempfile.mkdtemp(prefix="fleetrun-numba-"))
    try:
        (folder / "probe.py").write_text(PROBE)
        env = {**os.environ, "PYTHONPATH": f"{folder}{os.pathsep}{ROOT}", "PWD": str(folder),
               "FLEETRUN_CACHE_DIR": str(folder / "maps"), "OMP_NUM_THREADS": "1"}
        cpu_seconds([sys.executable, "-c", CASES["+ one cached @njit call"]], env)   # compiles, fills the cache
        best = {name: min(cpu_seconds([sys.executable, "-c", code], env) for _ in range(args.rounds))
                for name, code in CASES.items()}
        print(f"load average {os.getloadavg()[0]:.2f}; CPU seconds of a new process, best of {args.rounds}:")
        for name, seconds in best.items():
            print(f"  {name:45s} {seconds:.2f} s")
        if args.fleet:
            run = ("import sys; sys.argv = ['fleetrun', 'run', {fleet!r}, '--out', {out!r}, '-q']\n"
                   "from fleetrun.cli import main\ntry:\n    main()\nexcept SystemExit:\n    pass")
            code = run.format(fleet=str(args.fleet.resolve()), out=str(folder / "out"))
            cpu_seconds([sys.executable, "-c", code], env)                                # the map cache
            for k in range(args.rounds):
                plain = cpu_seconds([sys.executable, "-c", code], env)
                numba = cpu_seconds([sys.executable, "-c", "import numpy as np, probe; probe.total(np.ones(3))\n"
                                     + code], env)
                print(f"  round {k + 1}: fleetrun run {plain:.2f} s, with numba's start {numba:.2f} s "
                      f"(+{numba - plain:.2f} s); load {os.getloadavg()[0]:.2f}", flush=True)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
