"""Typed records the selection hands on: accepted effects, findings, what is left, drift.

:func:`fleetrun.diagnose.engine.select` returns a :class:`Selection`; :mod:`fleetrun.diagnose`
turns it into diagnosis.json with :meth:`Selection.as_json`, whose field names are the
interface of docs/diagnose.md ("diagnosis.json"). Every record is frozen: a step that changes
an accepted effect (a joint refit of its shape, its final coefficient) makes a new one with
:func:`dataclasses.replace`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import numpy as np

from fleetrun.diagnose.select import Candidate
from fleetrun.fileio import JsonDocument


def _round(x: float | None, digits: int = 5) -> float | None:
    return None if x is None else round(float(x), digits)


@dataclass(frozen=True)
class Segment:
    """A located stretch of the residual (:func:`fleetrun.diagnose.locate.segments`): start and
    end [s] and its ``share`` of the residual's excess energy; diagnosis.json's
    ``mismatch.segments`` entries."""

    start_s: float
    end_s: float
    share: float

    def as_json(self) -> JsonDocument:
        return {"start_s": self.start_s, "end_s": self.end_s, "share": self.share}


@dataclass(frozen=True)
class DriverLink:
    """How strongly the residual follows one channel (:func:`fleetrun.diagnose.locate.drivers`):
    diagnosis.json's ``mismatch.drivers`` entries."""

    channel: str
    strength: float
    significant: bool
    null_threshold: float

    def as_json(self) -> JsonDocument:
        return {"channel": self.channel, "strength": self.strength, "significant": self.significant,
                "null_threshold": self.null_threshold}


@dataclass(frozen=True)
class Phase:
    """A phase of a recording (:func:`fleetrun.diagnose.integrals.phases`): the sample index
    span ``[start, end)`` and its label (``standstill``, ``driving``, ``UDDS bag 1``, ...)."""

    span: tuple[int, int]
    label: str


@dataclass(frozen=True)
class Integral:
    """One entry of diagnosis.json's ``integrals`` (:func:`fleetrun.diagnose.integrals.integrals`):
    the target integrated over a phase or a located segment, measured, model before and after
    the findings (``integral_unit``)."""

    start_s: float
    end_s: float
    measured: float
    before: float
    after: float
    kind: str
    label: str
    heldout: bool = False

    def as_json(self) -> JsonDocument:
        return {"start_s": self.start_s, "end_s": self.end_s, "measured": self.measured, "before": self.before,
                "after": self.after, "heldout": self.heldout, "kind": self.kind, "label": self.label}


@dataclass(frozen=True)
class Accepted:
    """An effect accepted into the model during the search.

    ``column``: its effect on the target per unit of its linear parameter at ``shape``;
    ``before``/``after``: held-out RMSE without and with it when it was accepted (target
    units); ``coefficient``: the linear parameter of the final joint refit (None before it).
    """

    cand: Candidate
    shape: dict[str, float]
    column: np.ndarray = field(repr=False, compare=False)
    before: float
    after: float
    gain: float
    coefficient: float | None = None
    #: a block refitted after the selection: the factor of its penalty kept (None: not refitted)
    relaxed: float | None = None

    @property
    def id(self) -> str:
        return self.cand.id

    def term(self) -> tuple[np.ndarray, float, float]:
        """The effect as a model term ``(column, lower, upper)``."""
        return (self.column, self.cand.lower, self.cand.upper)


@dataclass(frozen=True)
class Finding:
    """One entry of diagnosis.json's ``findings``."""

    effect: str
    parameters: dict[str, float]
    heldout_rmse_before: float
    heldout_rmse_after: float
    explanation: str
    seed: str

    def as_json(self) -> JsonDocument:
        return {"effect": self.effect, "parameters": dict(self.parameters),
                "heldout_rmse_before": self.heldout_rmse_before,
                "heldout_rmse_after": self.heldout_rmse_after,
                "explanation": self.explanation, "seed": self.seed}


@dataclass(frozen=True)
class Drift:
    """The ``sensor_drift`` check (docs/diagnose.md, "Drift"): a slowly changing gain and
    offset of the target's sensor, piecewise linear in time, fitted to what the accepted
    physics leaves. ``gain_change``: the fitted gain's largest excursion from its start (a
    fraction); ``offset_change``: the same for the offset (target units); ``start_s``/``end_s``:
    where the fitted drift does 10-90 % of its moving."""

    significant: bool
    heldout_gain: float
    gain_change: float
    offset_change: float
    start_s: float
    end_s: float

    def as_json(self) -> JsonDocument:
        return {"significant": self.significant, "heldout_gain": round(self.heldout_gain, 5),
                "gain_change": round(self.gain_change, 6), "offset_change": round(self.offset_change, 6),
                "start_s": round(self.start_s, 3), "end_s": round(self.end_s, 3)}


@dataclass(frozen=True)
class Unexplained:
    """diagnosis.json's ``unexplained``: what the accepted findings leave, by its size.

    ``significant``: the generic description of the remainder beats the shift null and cuts
    its held-out error by more than :data:`fleetrun.diagnose.openworld.UNEXPLAINED_MIN_GAIN`
    even after a small form mismatch of the accepted effects has taken what it can (or the
    drift check is significant). ``energy_share``: the structured part of the remainder (its
    mean square above the noise) as a share of the structured part of the original mismatch;
    ``form_share``: the share of the original mismatch's structured energy a form mismatch
    of the accepted effects could leave (:func:`fleetrun.diagnose.openworld.form_columns`);
    ``integral_share``: the phase-integral error left as a share of the error before (set by
    :func:`fleetrun.diagnose.analyse` once the integrals are known).
    """

    significant: bool
    rmse: float
    noise_rmse: float
    heldout_gain: float
    energy_share: float | None
    form_share: float | None
    segments: list[Segment]
    drivers: list[DriverLink]
    drift: Drift | None = None
    integral_share: float | None = None

    def as_json(self) -> JsonDocument:
        out = {"significant": self.significant, "rmse": round(self.rmse, 6),
               "noise_rmse": round(self.noise_rmse, 6), "heldout_gain": round(self.heldout_gain, 5),
               "energy_share": _round(self.energy_share), "form_share": _round(self.form_share),
               "integral_share": _round(self.integral_share),
               "segments": [x.as_json() for x in self.segments], "drivers": [x.as_json() for x in self.drivers]}
        if self.drift is not None:
            out["drift"] = self.drift.as_json()
        return out


@dataclass(frozen=True)
class Selection:
    """What :func:`fleetrun.diagnose.engine.select` decided.

    ``findings`` in the order accepted; ``candidates``, ``ambiguities``, ``descriptions`` and
    ``rounds`` are JSON-ready lists (their fields are diagnosis.json's); ``fitted_effects``:
    the findings (and the moves of the calibration terms) in target units;
    ``accepted``/``initial_coefficients``: what :func:`fleetrun.diagnose.engine.fitted_on`
    needs to evaluate them on a finer grid.
    """

    findings: tuple[Finding, ...]
    candidates: list
    ambiguities: list
    descriptions: list
    unexplained: Unexplained
    significant: bool
    threshold: float | None
    rounds: list
    fitted_effects: np.ndarray = field(repr=False)
    baseline_heldout_rmse: float | None
    accepted: tuple[Accepted, ...] = ()
    initial_coefficients: tuple[float, ...] = ()

    def as_json(self) -> JsonDocument:
        """The selection's part of diagnosis.json."""
        return {"findings": [f.as_json() for f in self.findings], "candidates": self.candidates,
                "ambiguities": self.ambiguities, "descriptions": self.descriptions,
                "unexplained": self.unexplained.as_json()}
