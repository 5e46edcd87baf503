"""A population fit on disk: ``fit-population`` writes it, ``report`` and ``export`` read it.

The folder holds ``population.npz`` (the hyper-posterior draws, each unit's pooled draws, the
new-unit predictive, the structures' evidence) and ``units/<i>.npz``, each unit's own fit
(:func:`bayes_imu.inference.archive.save_fit`), so a report or an export given the folder reads
the population instead of fitting its units and sampling the population again.
"""

import json
import zipfile
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..noise.avar_forms import NoiseModel
from .archive import _check_sizes, load_fit, save_fit
from .population import PopulationResult, UnitPosterior
from .selection import CandidateScore

__all__ = ["save_population", "load_population", "is_population_folder", "POPULATION_NAME"]

POPULATION_NAME = "population.npz"
_FORMAT = 1


def is_population_folder(folder):
    """Whether ``folder`` holds a population fit (:data:`POPULATION_NAME`)."""
    return (Path(folder) / POPULATION_NAME).is_file()


def _json_number(value):
    value = float(value)
    return value if np.isfinite(value) else None


def save_population(pop, folder):
    """Write ``pop`` (a :class:`PopulationResult`) into ``folder`` (module docstring)."""
    folder = Path(folder)
    (folder / "units").mkdir(exist_ok=True)
    for i, fit in enumerate(pop.unit_fits):
        save_fit(fit, folder / "units" / f"{i}.npz")
    meta = {
        "format": _FORMAT,
        "terms": list(pop.model.terms),
        "dt": pop.model.dt,
        "labels": list(pop.labels),
        "selected": int(pop.selected),
        "diagnostics": pop.diagnostics,
        "spread_scale": pop.spread_scale,
        "seed": pop.seed if isinstance(pop.seed, (int, type(None))) else str(pop.seed),
        "structures": [
            {
                "terms": list(s.terms),
                "log_evidence": _json_number(s.log_evidence),
                "se": _json_number(s.log_evidence_se),
            }
            for s in pop.structures
        ],
        "units": [{"record_s": u.record_s, "label": u.label} for u in pop.units],
        "new_unit": {"record_s": pop.new_unit.record_s, "label": pop.new_unit.label},
    }
    arrays = {
        "mean": pop.mean,
        "spread": pop.spread,
        "per_unit_evidence": pop.per_unit_evidence,
        "new_samples": pop.new_unit.samples,
    }
    if pop.new_unit.discrepancy is not None:
        arrays["new_discrepancy"] = pop.new_unit.discrepancy
    for i, u in enumerate(pop.units):
        arrays[f"unit_{i}_samples"] = u.samples
        if u.discrepancy is not None:
            arrays[f"unit_{i}_discrepancy"] = u.discrepancy
    with open(folder / POPULATION_NAME, "wb") as f:
        np.savez_compressed(f, meta=np.array(json.dumps(meta)), **arrays)


def load_population(folder):
    """The :class:`PopulationResult` :func:`save_population` wrote into ``folder``."""
    folder = Path(folder)
    file = folder / POPULATION_NAME
    if not file.is_file():
        raise InputError(
            f"{folder}: no {POPULATION_NAME}; expected a folder written by bayes-imu fit-population"
        )
    _check_sizes(file)
    try:
        with np.load(file, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
        meta = json.loads(str(data["meta"]))
        if meta.get("format") != _FORMAT:
            raise KeyError("format")
        model = NoiseModel(tuple(meta["terms"]), meta["dt"])
        fits = tuple(load_fit(folder / "units" / f"{i}.npz") for i in range(len(meta["labels"])))
        units = tuple(
            UnitPosterior(
                model,
                data[f"unit_{i}_samples"],
                u["record_s"],
                u["label"],
                data.get(f"unit_{i}_discrepancy"),
            )
            for i, u in enumerate(meta["units"])
        )
        new = meta["new_unit"]
        new_unit = UnitPosterior(
            model, data["new_samples"], new["record_s"], new["label"], data.get("new_discrepancy")
        )
        structures = tuple(
            CandidateScore(
                tuple(s["terms"]),
                np.nan if s["log_evidence"] is None else s["log_evidence"],
                np.nan if s["se"] is None else s["se"],
                np.nan,
                np.empty(0),
            )
            for s in meta["structures"]
        )
    except (
        OSError,
        ValueError,
        KeyError,
        TypeError,
        EOFError,
        zipfile.BadZipFile,
        RecursionError,
    ) as exc:
        raise InputError(
            f"{file}: not a readable bayes_imu population archive ({type(exc).__name__})"
        ) from None
    return PopulationResult(
        model,
        tuple(meta["labels"]),
        fits,
        units,
        data["mean"],
        data["spread"],
        new_unit,
        structures,
        data["per_unit_evidence"],
        meta["selected"],
        meta["diagnostics"],
        meta["spread_scale"],
        meta["seed"],
    )
