"""A fit saved with its folder (``fit.npz``) and read back, so reports reuse fits instead of
refitting.

``fit.npz`` (NumPy archive, no pickles) holds everything a
:class:`~bayes_imu.inference.fit.FitResult` needs except the ArviZ ``InferenceData``
(``posterior.nc`` beside it): the Allan variance, the draws of the selected model and of every
model-averaging component, the candidates' evidences, the adequacy and stationarity checks, the
covariance and the diagnostics.

An archive is untrusted input (a report reads fit folders it did not write): :func:`load_fit`
reads the arrays' headers first and refuses an archive whose arrays declare more bytes than
:data:`MAX_EXPANSION` times its size (a 6 MB file asking for a 6 GiB array), or an object
array; then checks every field (:func:`_validate`: finite values, positive where physical,
consistent shapes, a known format and terms) and refuses a damaged or crafted one with a
one-line :class:`~bayes_imu.errors.InputError` naming the field, instead of putting NaN or
zero noise values into ``imu.yaml``.
"""

import json
import math
import zipfile
from pathlib import Path

import numpy as np

from ..allan.contrast import PhaseContrasts
from ..allan.estimator import AllanResult, SegmentAllan
from ..errors import InputError
from .._version import __version__
from .fit import FitResult, MixtureComponent
from ..io.readers import read_json_object
from ..noise.avar_forms import NoiseModel
from .selection import Adequacy, CandidateScore
from .stationarity import STATIONARITY_ALPHA, Stationarity

__all__ = ["save_fit", "load_fit", "fit_axes", "write_netcdf", "ARCHIVE_NAME"]

ARCHIVE_NAME = "fit.npz"
#: largest ratio of the arrays' declared bytes to the archive's size (``savez_compressed`` of a
#: fit: about 1.3)
MAX_EXPANSION = 64
_FORMAT = 1
_ALLAN_ARRAYS = ("tau", "m", "avar", "adev", "n_terms", "edf", "alpha", "avar_low", "avar_high")


def save_fit(fit, path):
    """Write ``fit`` to ``path`` (a ``.npz`` file)."""
    a, q, st = fit.allan, fit.adequacy, getattr(fit, "stationarity", None)
    meta = {
        "format": _FORMAT,
        "terms": list(fit.model.terms),
        "dt": fit.model.dt,
        "likelihood": fit.likelihood,
        "selected": int(fit.selected),
        "widened": bool(fit.widened),
        "diagnostics": fit.diagnostics,
        "seed": fit.seed if isinstance(fit.seed, (int, type(None))) else str(fit.seed),
        "allan": {
            "confidence": a.confidence,
            "rate_hz": a.rate_hz,
            "n_samples": int(a.n_samples),
            "sensor": getattr(a, "sensor", None),
        },
        "candidates": [
            {
                "terms": list(c.terms),
                "log_evidence": c.log_evidence,
                "se": c.log_evidence_se,
                "ess": c.ess,
                "method": c.method,
            }
            for c in fit.candidates
        ],
        "mixture": [{"terms": list(c.terms), "probability": c.probability} for c in fit.mixture],
        "adequacy": None if q is None else {**q.to_dict(), "residuals": None},
        "segments": None if a.segments is None else {"n_samples": int(a.segments.n_samples)},
        "contrasts": None
        if getattr(a, "contrasts", None) is None
        else {"n_cal": int(a.contrasts.n_cal)},
        "stationarity": None
        if st is None
        else {
            "stationary": bool(st.stationary),
            "p_value": float(st.p_value),
            "worst_tau_s": float(st.worst_tau_s),
            "alpha": float(st.alpha),
        },
    }
    arrays = {f"allan_{k}": getattr(a, k) for k in _ALLAN_ARRAYS}
    arrays.update(
        samples=fit.samples,
        log_prob=fit.log_prob,
        covariance=fit.covariance,
        probabilities=np.asarray(fit.probabilities if fit.probabilities is not None else []),
    )
    for i, c in enumerate(fit.candidates):
        arrays[f"mode_{i}"] = np.asarray(c.mode)
    for i, c in enumerate(fit.mixture):
        arrays[f"mixture_{i}"] = c.samples
    if q is not None:
        arrays["residuals"] = np.asarray(q.residuals)
    if a.segments is not None:
        arrays.update(segments_m=a.segments.m, segments_avar=a.segments.avar)
    if getattr(a, "contrasts", None) is not None:
        arrays.update(contrasts_k=a.contrasts.k, contrasts_mean_square=a.contrasts.mean_square)
        if a.contrasts.mean_square_2 is not None:
            arrays.update(contrasts_mean_square_2=a.contrasts.mean_square_2)
    if st is not None:
        arrays.update(
            stationarity_tau=st.tau_s,
            stationarity_adev=st.segment_adev,
            stationarity_spread=st.spread,
        )
    with open(path, "wb") as f:
        np.savez_compressed(f, meta=np.array(json.dumps(meta)), **arrays)


def fit_axes(folder):
    """``[(axis, folder, summary)]`` of a ``bayes-imu fit`` folder: its one axis, or each axis of a
    several-column fit (the sub-folders its ``summary.json`` lists under ``axes``)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{folder}: not a folder; expected a folder written by bayes-imu fit")
    if not (folder / "summary.json").exists():  # not "folder/summary.json: no such file"
        raise InputError(f"{folder}: no summary.json in it: not a folder written by bayes-imu fit")
    summary = read_json_object(folder / "summary.json", "a bayes-imu fit summary")
    if "axes" not in summary:
        return [(str(summary.get("column", folder.name)), folder, summary)]
    return [(axis, folder / entry["folder"], entry) for axis, entry in summary["axes"].items()]


def load_fit(path):
    """Read a :class:`~bayes_imu.inference.fit.FitResult` from a fit folder or its ``fit.npz``.

    ``inference_data`` is ``None`` (read ``posterior.nc`` with ArviZ for it).
    """
    path = Path(path)
    file = path / ARCHIVE_NAME if path.is_dir() else path
    if not file.is_file():
        hint = (
            " (a folder written by an older bayes_imu: run bayes-imu fit again)"
            if path.is_dir()
            else ""
        )
        raise InputError(
            f"{path}: no {ARCHIVE_NAME}; expected a folder written by bayes-imu fit{hint}"
        )
    _check_sizes(file)
    try:
        with np.load(file, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
        meta = json.loads(str(data["meta"]))
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, RecursionError) as exc:
        raise InputError(f"{file}: not a readable bayes_imu fit archive ({_short(exc)})") from None
    if not isinstance(meta, dict) or meta.get("format") != _FORMAT:
        shown = meta.get("format") if isinstance(meta, dict) else None
        raise InputError(f"{file}: archive format {_short(shown)}; this bayes_imu reads format "
                         f"{_FORMAT}")
    try:
        _validate(meta, data)
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise InputError(f"{file}: damaged or crafted fit archive: {_short(exc)}") from None
    seg = meta.get("segments")
    segments = (
        None
        if seg is None
        else SegmentAllan(data["segments_m"], data["segments_avar"], seg["n_samples"])
    )
    con = meta.get("contrasts")
    n_all, rate = meta["allan"]["n_samples"], meta["allan"]["rate_hz"]
    contrasts = (
        None
        if con is None
        else PhaseContrasts(
            data["contrasts_k"],
            con["n_cal"],
            data["contrasts_mean_square"],
            n_all - con["n_cal"] - data["contrasts_k"] + 1,
            rate,
            n_all,
            data["contrasts_mean_square_2"] if "contrasts_mean_square_2" in data else None,
        )
    )
    allan = AllanResult(
        **{k: data[f"allan_{k}"] for k in _ALLAN_ARRAYS},
        confidence=meta["allan"]["confidence"],
        rate_hz=rate,
        n_samples=n_all,
        segments=segments,
        contrasts=contrasts,
        sensor=meta["allan"].get("sensor"),
    )
    st = meta.get("stationarity")
    steady = (
        None
        if st is None
        else Stationarity(
            st["stationary"],
            st["p_value"],
            st["worst_tau_s"],
            data["stationarity_tau"],
            data["stationarity_adev"],
            data["stationarity_spread"],
            alpha=st.get("alpha", STATIONARITY_ALPHA),  # archives before the field: the default
        )
    )
    model = NoiseModel(tuple(meta["terms"]), meta["dt"])
    candidates = tuple(
        CandidateScore(
            tuple(c["terms"]),
            c["log_evidence"],
            c["se"],
            c["ess"],
            data[f"mode_{i}"],
            c.get("method", "importance"),
        )
        for i, c in enumerate(meta["candidates"])
    )
    mixture = tuple(MixtureComponent(tuple(c["terms"]), c["probability"], data[f"mixture_{i}"])
                    for i, c in enumerate(meta["mixture"]))
    q = meta["adequacy"]
    adequacy = (
        None
        if q is None
        else Adequacy(
            q["adequate"],
            q["p_value"],
            q["statistic"],
            q["dof"],
            data["residuals"],
            q["worst_tau_s"],
            tuple(q["at_prior_bound"]),
        )
    )
    probabilities = data["probabilities"] if data["probabilities"].size else None
    return FitResult(
        model,
        data["samples"],
        data["log_prob"],
        allan,
        candidates,
        meta["selected"],
        meta["diagnostics"],
        meta["likelihood"],
        data["covariance"],
        meta["seed"],
        None,
        adequacy,
        probabilities,
        mixture,
        meta["widened"],
        steady,
    )


def _short(value, limit=80):
    text = "".join(c if c.isprintable() else "?" for c in str(value))
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _check_sizes(file):
    """Refuse an archive whose arrays declare more than :data:`MAX_EXPANSION` times its size, or
    hold objects,
    from the headers alone (nothing allocated)."""
    size = file.stat().st_size
    total = 0
    try:
        with zipfile.ZipFile(file) as z:
            for info in z.infolist():
                with z.open(info) as member:
                    version = np.lib.format.read_magic(member)
                    read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                            else np.lib.format.read_array_header_2_0)
                    shape, _, dtype = read(member)
                if dtype.hasobject:
                    raise InputError(f"{file}: field {_short(info.filename)} holds Python "
                                     "objects; expected numbers")
                total += math.prod(shape) * dtype.itemsize
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, RuntimeError) as exc:
        raise InputError(f"{file}: not a readable bayes_imu fit archive ({_short(exc)})") from None
    if total > MAX_EXPANSION * size + 2**20:
        raise InputError(f"{file}: its arrays declare {total:.3g} bytes, more than "
                         f"{MAX_EXPANSION} times the archive's "
                         f"{size} bytes; a damaged or crafted archive (nothing was allocated)")


def _validate(meta, data):
    """Raise ``ValueError`` naming the first field of a loaded archive that no fit writes."""
    from ..noise import TERMS

    def field(name, *, positive=False, ndim=None, length=None, finite=True):
        a = data[name]
        if a.dtype.kind not in "fiu":
            raise ValueError(f"field {name!r} has dtype {a.dtype}; expected numbers")
        if ndim is not None and a.ndim != ndim:
            raise ValueError(f"field {name!r} has shape {a.shape}; expected {ndim} dimension(s)")
        if length is not None and a.shape[0] != length:
            raise ValueError(f"field {name!r} has {a.shape[0]} rows; expected {length}")
        if finite and not np.all(np.isfinite(a)):
            raise ValueError(f"field {name!r} holds NaN or infinite values")
        if positive and not np.all(a > 0):
            raise ValueError(
                f"field {name!r} holds zero or negative values; expected positive ones"
            )
        return a

    terms = meta["terms"]
    if not isinstance(terms, list) or not terms or not all(t in TERMS for t in terms):
        raise ValueError(f"field 'terms' = {terms!r}; expected a list of {', '.join(TERMS)}")
    for key, value in (("dt", meta["dt"]), ("allan.rate_hz", meta["allan"]["rate_hz"]),
                       ("allan.confidence", meta["allan"]["confidence"])):
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not (math.isfinite(value) and value > 0)
        ):
            raise ValueError(f"field {key!r} = {value!r}; expected a positive number")
    if abs(meta["dt"] * meta["allan"]["rate_hz"] - 1.0) > 1e-9:
        raise ValueError(f"fields 'dt' and 'allan.rate_hz' disagree ({meta['dt']!r} s, "
                         f"{meta['allan']['rate_hz']!r} Hz)")
    n_samples = meta["allan"]["n_samples"]
    if isinstance(n_samples, bool) or not isinstance(n_samples, int) or n_samples < 4:
        raise ValueError(f"field 'allan.n_samples' = {n_samples!r}; expected a whole number of at "
                         "least 4")
    n_tau = field("allan_tau", positive=True, ndim=1).shape[0]
    for k in _ALLAN_ARRAYS:
        field(
            f"allan_{k}",
            positive=k in ("tau", "m", "avar", "adev", "n_terms", "edf", "avar_low", "avar_high"),
            ndim=1,
            length=n_tau,
        )
    n_parameters = len(NoiseModel(tuple(terms), meta["dt"]).parameter_names) + bool(meta["widened"])
    samples = field("samples", positive=True, ndim=2)
    if samples.shape[1] != n_parameters or samples.shape[0] < 1:
        raise ValueError(f"field 'samples' has shape {samples.shape}; expected (draws, "
                         f"{n_parameters}) for "
                         f"{' + '.join(terms)}")
    field("log_prob", ndim=1, length=samples.shape[0])
    covariance = field("covariance", ndim=2)
    if covariance.shape != (n_tau, n_tau):
        raise ValueError(f"field 'covariance' has shape {covariance.shape}; expected ({n_tau}, "
                         f"{n_tau})")
    for i, c in enumerate(meta["mixture"]):
        mix = field(f"mixture_{i}", positive=True, ndim=2)
        if mix.shape[1] - len(NoiseModel(tuple(c["terms"]), meta["dt"]).parameter_names) not in (
            0,
            1,
        ):
            raise ValueError(f"field 'mixture_{i}' has shape {mix.shape}; expected one column per "
                             "parameter of "
                             f"{' + '.join(map(str, c['terms']))}")
        p = c["probability"]
        if isinstance(p, bool) or not isinstance(p, (int, float)) or not 0 <= p <= 1:
            raise ValueError(f"field 'mixture[{i}].probability' = {p!r}; expected a number in [0, "
                             "1]")
    for i, _ in enumerate(meta["candidates"]):
        field(f"mode_{i}")
    field("probabilities")
    if not 0 <= meta["selected"] < len(meta["candidates"]):
        raise ValueError(f"field 'selected' = {meta['selected']!r}; expected an index of the "
                         f"{len(meta['candidates'])} "
                         "candidates")
    if meta.get("adequacy") is not None:
        field("residuals", ndim=1)


def write_netcdf(fit, path):
    """The posterior as an ArviZ NetCDF file: what ``fit.inference_data.to_netcdf(path)`` writes,
    without ArviZ.

    ``arviz.from_netcdf`` (and xarray, group by group) reads it as :attr:`FitResult.inference_data`:
    groups ``posterior`` (``log_<name>`` and ``<name>`` of each parameter), ``sample_stats``
    (``lp``), ``log_likelihood`` (``allan``), each ``(chain, draw)`` with walkers as chains, and
    ``observed_data`` (``avar`` over ``tau`` [s]); the fit's attributes (``terms``, ``likelihood``,
    ``bayes_imu_version``) on the file (tested against ArviZ's own file). The NetCDF-4 file is
    written with h5netcdf, a dependency of ArviZ's NetCDF backend: importing ArviZ and xarray
    costs more than the rest of a fit's outputs (timings: docs/speed_under_load.md#imports).
    """
    chains = fit.chains
    if chains is None:
        raise InputError(
            "write_netcdf: this fit has no chains (read back from fit.npz); posterior.nc is "
            "written by the fit that sampled them"
        )
    names = fit.parameter_names
    n_draws, n_walkers = chains.chain.shape[:2]
    sampled = {"chain": np.arange(n_walkers), "draw": np.arange(n_draws)}
    dims = ("chain", "draw")
    posterior = {f"log_{n}": (dims, chains.chain[:, :, i].T) for i, n in enumerate(names)}
    posterior.update({n: (dims, np.exp(chains.chain[:, :, i].T)) for i, n in enumerate(names)})
    groups = {
        "posterior": (sampled, posterior),
        "log_likelihood": (sampled, {"allan": (dims, chains.log_likelihood.T)}),
        "sample_stats": (sampled, {"lp": (dims, chains.log_prob.T)}),
        "observed_data": ({"tau": fit.allan.tau}, {"avar": (("tau",), fit.allan.avar)}),
    }
    attrs = {
        "terms": " ".join(fit.model.terms),
        "likelihood": fit.likelihood,
        "bayes_imu_version": __version__,
    }
    _write_groups(path, groups, attrs)


def _write_groups(path, groups, attrs):
    """A NetCDF-4 file of ``groups`` = ``{name: (coordinates, variables)}``, ``coordinates`` =
    ``{dim: values}``, ``variables`` = ``{name: (dims, values)}``, as xarray encodes them
    (zlib-compressed, NaN fill value on floats); each group stamped with its creation time and this
    library, the file with ``attrs``."""
    from datetime import datetime, timezone

    import h5netcdf

    created = datetime.now(timezone.utc).isoformat()
    with h5netcdf.File(str(path), "w") as f:
        f.attrs.update(attrs)
        for name, (coordinates, variables) in groups.items():
            g = f.create_group(name)
            g.dimensions = {dim: len(values) for dim, values in coordinates.items()}
            for dim, values in {
                **{d: ((d,), v) for d, v in coordinates.items()},
                **variables,
            }.items():
                dims, values = values
                values = np.asarray(values)
                fill = {"fillvalue": np.nan} if values.dtype.kind == "f" else {}
                g.create_variable(dim, dims, data=values, compression="gzip", **fill)
            g.attrs.update(
                created_at=created,
                inference_library="bayes_imu",
                inference_library_version=__version__,
            )
