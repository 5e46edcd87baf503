"""Is a unit within its datasheet? P(within spec) of each datasheet value.

A specification file (JSON or TOML) gives the vendor's values in the datasheet units of
:func:`bayes_imu.noise.datasheet.datasheet` (gyro: ``angle_random_walk`` deg/sqrt(h),
``bias_instability`` deg/h, ``rate_random_walk`` deg/h/sqrt(h), ...; accelerometer:
``velocity_random_walk`` m/s/sqrt(h), ``bias_instability`` ug, ...)::

    kind = "gyro"
    angle_random_walk = 0.15
    bias_instability = { value = 5.0, unit = "deg/h" }   # a unit, if given, must be that one

Each value is a maximum: :func:`check_datasheet` gives ``P(value <= spec)`` over the posterior
draws. The conversions are :func:`~bayes_imu.noise.datasheet.datasheet`'s own, read off it
(each is ``c * parameter**p``, found by evaluating it at single-draw stand-ins, and checked
at a third point), so that a datasheet row has one definition.
"""

import math
from pathlib import Path

import numpy as np

from ..errors import InputError, ModelError
from .datasheet import datasheet
from .model import TERM_PARAMETERS, TERMS, NoiseModel

__all__ = [
    "read_datasheet_spec",
    "datasheet_conversions",
    "check_datasheet",
    "verdict",
    "spec_model",
    "KINDS",
]

KINDS = ("gyro", "accel")
#: probability above which a value is within spec, and below whose complement it is outside
CONFIDENT = 0.95


class _Probe:
    """A one-draw posterior of every term (what :func:`datasheet` reads): every parameter (and
    the derived ``noise_density``) equal to ``x``, or each its own value (``distinct``) to tell
    which one a row reads."""

    def __init__(self, x, distinct=False):
        self.model = NoiseModel(TERMS, 1.0)
        self.parameter_names = self.model.parameter_names
        names = self.parameter_names + ("noise_density",)
        self.values = {n: float(x) * (_PRIMES[i] if distinct else 1.0) for i, n in enumerate(names)}
        self.samples = np.array([[self.values[n] for n in self.parameter_names]])

    def draws(self, name):
        return np.array([self.values[name]])


_PRIMES = (2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53)


def datasheet_conversions(kind):
    """Name -> ``(source, c, p, unit)``: the datasheet value is ``c * draws(source)**p``."""
    if kind not in KINDS:
        raise InputError(f"kind={kind!r}: expected one of {', '.join(KINDS)}")
    at = {x: datasheet(_Probe(x), kind) for x in (1.0, 4.0, 9.0)}
    probe = _Probe(1.0, distinct=True)
    tagged = datasheet(probe, kind)
    out = {}
    for name, row in at[1.0].items():
        c = row["median"]
        p = math.log(at[4.0][name]["median"] / c) / math.log(4.0)
        if not math.isclose(at[9.0][name]["median"], c * 9.0**p, rel_tol=1e-9) or p <= 0:
            raise ModelError(
                f"datasheet row {name!r}: not a power of its parameter; cannot check a spec"
            )
        x = (tagged[name]["median"] / c) ** (1.0 / p)
        source = [n for n, v in probe.values.items() if math.isclose(v, x, rel_tol=1e-6)]
        if len(source) != 1:
            raise ModelError(f"datasheet row {name!r}: its parameter was not found")
        out[name] = (source[0], c, p, row["unit"])
    return out


def read_datasheet_spec(path):
    """``(kind, {name: value})`` of a JSON or TOML specification file, validated."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read the datasheet file ({exc})") from None
    try:
        if path.suffix.lower() == ".toml":
            import tomllib

            doc = tomllib.loads(text)
        else:
            import json

            doc = json.loads(text)
    except ValueError as exc:
        raise InputError(
            f"{path}: not valid {'TOML' if path.suffix.lower() == '.toml' else 'JSON'} ({exc})"
        ) from None
    if not isinstance(doc, dict) or doc.get("kind") not in KINDS:
        raise InputError(
            f'{path}: expected an object with kind = "gyro" or "accel" and datasheet values'
        )
    kind = doc["kind"]
    rows = datasheet_conversions(kind)
    spec = {}
    for name, entry in doc.items():
        if name == "kind":
            continue
        if name not in rows:
            raise InputError(
                f"{path}: {name!r}: expected one of {', '.join(rows)} ({kind} datasheet values)"
            )
        expected = rows[name][3]
        value, unit = (
            (entry.get("value"), entry.get("unit", expected))
            if isinstance(entry, dict)
            else (entry, expected)
        )
        if unit != expected:
            raise InputError(f"{path}: {name} unit {unit!r}: expected {expected!r}")
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not (math.isfinite(value) and value > 0)
        ):
            raise InputError(
                f"{path}: {name} = {value!r}: expected a positive number in {expected}"
            )
        spec[name] = float(value)
    if not spec:
        raise InputError(f"{path}: no datasheet values; expected some of {', '.join(rows)}")
    return kind, spec


def check_datasheet(posterior, kind, spec):
    """Name -> ``{"spec", "unit", "probability", "median", "q95"}``: ``P(value <= spec)``.

    ``posterior`` fitted in SI (as :func:`~bayes_imu.noise.datasheet.datasheet`); a value whose
    term the model lacks gets ``probability`` ``None`` (``"in_model": False``).
    """
    rows = datasheet_conversions(kind)
    present = set(posterior.parameter_names) | {"noise_density"}
    out = {}
    for name, limit in spec.items():
        source, c, p, unit = rows[name]
        if source not in present:
            out[name] = {"spec": limit, "unit": unit, "probability": None, "in_model": False}
            continue
        value = c * np.asarray(posterior.draws(source), float) ** p
        out[name] = {
            "spec": limit,
            "unit": unit,
            "probability": float(np.mean(value <= limit)),
            "in_model": True,
            "median": float(np.median(value)),
            "q95": float(np.quantile(value, 0.95)),
        }
    return out


def spec_model(kind, spec, rate_hz):
    """``(NoiseModel, params)`` of datasheet values: the terms whose parameters are all given."""
    rows = datasheet_conversions(kind)
    params = {}
    for name, value in spec.items():
        source, c, p, _ = rows[name]
        params[source] = (value / c) ** (1.0 / p)
    if "noise_density" in params:
        params["noise_variance"] = params.pop("noise_density") ** 2 * rate_hz
    terms = [t for t, names in TERM_PARAMETERS.items() if names and all(n in params for n in names)]
    unused = sorted(set(params) - {n for t in terms for n in TERM_PARAMETERS[t]})
    if not terms or unused:
        raise InputError(
            f"datasheet values: {', '.join(unused) or 'none'} without the rest of their term; "
            "give a Gauss-Markov sigma with its time constant"
        )
    return NoiseModel(tuple(terms), 1.0 / rate_hz), params


def verdict(results):
    """One line: which values are within spec, outside it, or undecided (posterior probability)."""
    within, outside, open_ = [], [], []
    for name, r in results.items():
        if r["probability"] is None:
            open_.append(f"{name} (not in the model)")
        elif r["probability"] >= CONFIDENT:
            within.append(f"{name} P={r['probability']:.2f}")
        elif r["probability"] <= 1.0 - CONFIDENT:
            outside.append(
                f"{name} P={r['probability']:.2f} (median {r['median']:.3g} > spec {r['spec']:.3g} "
                f"{r['unit']})"
            )
        else:
            open_.append(f"{name} P={r['probability']:.2f}")
    head = (
        "OUTSIDE the datasheet"
        if outside
        else ("within the datasheet" if not open_ else "datasheet check open")
    )
    parts = [
        f"within spec: {', '.join(within)}" if within else "",
        f"outside: {', '.join(outside)}" if outside else "",
        f"undecided: {', '.join(open_)}" if open_ else "",
    ]
    return f"{head}: " + "; ".join(p for p in parts if p)
