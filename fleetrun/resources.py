"""Where the project's data folders are: ``models/``, ``templates/`` and ``inputs/``.

In a source checkout (or an editable install) they sit beside the package; an installed
fleetrun carries copies as ``fleetrun/_data/<name>`` (see ``pyproject.toml``).
"""
from __future__ import annotations

import tomllib
from functools import lru_cache
from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent


@lru_cache(maxsize=None)
def data_dir(name: str) -> Path:
    """The folder ``name`` (``models``, ``templates`` or ``inputs``)."""
    for candidate in (_PACKAGE.parent / name, _PACKAGE / "_data" / name):
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(f"fleetrun data folder '{name}' is missing from this installation")


def models_dir() -> Path:
    return data_dir("models")


def templates_dir() -> Path:
    return data_dir("templates")


def inputs_dir() -> Path:
    return data_dir("inputs")


@lru_cache(maxsize=None)
def model_file(name: str) -> dict:
    """The parsed TOML file ``models/<name>``, read once per process. Callers must not
    mutate the returned mapping (it is shared); copy what they change."""
    with open(models_dir() / name, "rb") as handle:
        return tomllib.load(handle)
