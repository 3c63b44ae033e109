"""Packaging of the data folders: models/, templates/ and inputs/ sit at the top of the
repository (data, not code) and are installed as ``fleetrun/_data/<name>`` so that a plain
``pip install .`` finds them (fleetrun/resources.py looks in both places)."""
import os

from setuptools import find_packages, setup

DATA_FOLDERS = ("models", "templates", "inputs")
SKIP = {"__pycache__"}

packages = find_packages(include=["fleetrun", "fleetrun.*"])
package_dir = {"fleetrun": "fleetrun"}
package_data = {}
for folder in DATA_FOLDERS:
    for dirpath, dirnames, filenames in os.walk(folder):
        dirnames[:] = sorted(d for d in dirnames if d not in SKIP and not d.startswith("."))
        name = "fleetrun._data." + ".".join(dirpath.split(os.sep))
        packages.append(name)
        package_dir[name] = dirpath
        package_data[name] = [f for f in filenames if not f.startswith(".") and not f.endswith(".pyc")]

setup(packages=packages, package_dir=package_dir, package_data=package_data)
