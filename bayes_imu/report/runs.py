"""Whole runs from request objects: a log's fit and a population fit, with every output file.

:func:`run_fit` is what ``bayes-imu fit`` does and what each log of ``fit-batch`` does
(:func:`~bayes_imu.report.fleet.run_batch`): read the log through the library pipeline
(:func:`~bayes_imu.allan.pipeline.allan_from_source`), fit every column, and write
``summary.json``, ``fit.npz``, ``posterior.nc``, the figures and (with ``request.sensor``) the
drift outputs into a staged ``out`` folder, moved into place only when complete
(:mod:`bayes_imu.report.output`). :func:`run_population` does the same for ``fit-population``.

They print nothing: what a caller shows comes back in the results (:class:`AxisRun`,
:class:`FitRun`, :class:`PopulationRun`), and is handed to optional callbacks as each stage
ends, so a command can say it while the run goes on. The command line only parses, calls these,
prints and chooses the exit status.
"""

import contextlib
import dataclasses
import warnings
from dataclasses import dataclass
from pathlib import Path

from ..allan.pipeline import allan_from_source
from ..errors import InputError
from .output import safe_folder_name, staged_folder
from .worker import PICTURE_FAILED_STATUS, OutputWriter, draw_picture
from .writers import (axis_summary, batch_summary, drift_check_summary, drift_outputs, fit_summary,
                      population_summary, write_allan_csv, write_drift, write_json)

__all__ = ["AxisRun", "FitRun", "PopulationRun", "BatchRun", "AllanRun", "run_fit", "fit_job",
           "run_fit_batch", "run_population", "run_allan", "input_files", "datasheet_summary",
           "column_warnings"]


@dataclass(frozen=True)
class AxisRun:
    """One column's fit and what was written of it.

    Attributes
    ----------
    column : str
        The column fitted.
    folder : str or None
        Its sub-folder of ``out`` (several columns), or ``None`` (one column, written in ``out``).
    result : FitResult
        The fit (:func:`~bayes_imu.inference.fit.fit_allan`).
    summary : dict
        Its ``summary.json``.
    drift : DriftOutput or None
        The drift bands (``request.sensor``), in their display units.
    check : DriftCheck or None
        The drift the record itself shows against the bands (``None`` where nothing is measured).
    """

    column: str
    folder: object
    result: object
    summary: dict
    drift: object = None
    check: object = None


@dataclass(frozen=True)
class FitRun:
    """A log's fit (:func:`run_fit`).

    Attributes
    ----------
    axes : tuple of AxisRun
        One per column, in the log's order.
    unit : str
        Unit of the fitted rates.
    info : dict
        What was read (``summary.json``'s ``input``).
    picture_failures : tuple of PictureFailure
        Each picture not drawn (the numbers were written).
    """

    axes: tuple
    unit: str
    info: dict
    picture_failures: tuple = ()


@dataclass(frozen=True)
class PopulationRun:
    """A population fit (:func:`run_population`).

    Attributes
    ----------
    population : PopulationResult
        The hierarchical fit (:func:`~bayes_imu.inference.population.fit_population`).
    summary : dict
        Its ``summary.json``.
    drift : DriftOutput or None
        The new unit's drift bands (``request.sensor``).
    picture_failures : tuple of PictureFailure
        Each picture not drawn.
    """

    population: object
    summary: dict
    drift: object = None
    picture_failures: tuple = ()


@dataclass(frozen=True)
class BatchRun:
    """A batch of fits (:func:`run_fit_batch`).

    Attributes
    ----------
    results : tuple of JobResult
        Each log's outcome, in the order of the logs.
    summary : dict
        Its ``batch.json``.
    seconds : float
        Wall time of the fits [s].
    """

    results: tuple
    summary: dict
    seconds: float


@dataclass(frozen=True)
class AllanRun:
    """An Allan deviation run (:func:`run_allan`).

    Attributes
    ----------
    read : SourceAllan
        What was read and its Allan variance.
    picture_failures : tuple of PictureFailure
        ``allan.png`` where it was not drawn (``allan.csv`` was written).
    """

    read: object
    picture_failures: tuple = ()


def input_files(*paths):
    """The input files an output must not replace (standard input, ``"-"``, is none)."""
    return [p for p in paths if p is not None and str(p) != "-"]


def _folder_names(columns):
    names = []
    for c in columns:
        names.append(safe_folder_name(c, names))
    return names


def run_fit(request, out, *, force=False, background=False, progress=False, on_read=None,
            on_axis=None):
    """Fit the log of ``request`` (a :class:`~bayes_imu.report.writers.FitRequest`) into ``out``.

    Parameters
    ----------
    request : FitRequest
    out : Path
        Output folder: new, empty, or a previous result with ``force``.
    force : bool
        Replace a previous bayes_imu result in ``out`` (never other files).
    background : bool
        Write the outputs from a second process (:class:`~bayes_imu.report.worker.OutputWriter`),
        which also seeks posterior modes for the fit.
    progress : bool
        Progress bars on standard error.
    on_read : callable, optional
        ``on_read(read)`` with the :class:`~bayes_imu.allan.pipeline.SourceAllan` once the log is
        read, before any fit.
    on_axis : callable, optional
        ``on_axis(axis)`` with each column's :class:`AxisRun` once its numbers are known (its
        files are written after the call returns).

    Returns
    -------
    FitRun

    Raises
    ------
    InputError
        Anything wrong with the request or the log (nothing is kept in ``out``).
    """
    from ..inference.fit import warm_up as warm_up_fit
    from ..inference.sampling import import_emcee
    from .plots import import_plotting

    # the worker imports ArviZ and the plotting libraries while this process reads and fits the
    # log (a second worker for the figures alone was tried: on 2 cores it slowed the fit more
    # than it saved)
    import_emcee()  # before the writer's thread starts: emcee without scipy.stats (import_emcee)
    with OutputWriter(background=background, warm=(import_plotting, warm_up_fit)) as writer:
        read = allan_from_source(request.source, purpose="fit", progress=progress)
        columns, unit, info = read.columns, read.unit, read.info
        if on_read is not None:
            on_read(read)
        inputs = input_files(request.source.log, request.source.allan_table)
        with staged_folder(out, force=force, inputs=inputs) as tmp:
            folders = [None] if len(columns) == 1 else _folder_names(columns)
            axes = []
            for allan, column, folder in zip(read.results, columns, folders):
                where = tmp if folder is None else tmp / folder
                with column_warnings(column):
                    axes.append(_fit_axis(request, allan, unit, info, column, folder, where,
                                          writer, progress=progress, on_axis=on_axis))
            if len(columns) > 1:
                summary = fit_summary({a.column: a.summary for a in axes}, info=info,
                                      seed=request.seed, folders=folders)
                write_json(tmp / "summary.json", summary)
            writer.wait()  # every output in the staging folder before it is moved into place
    failures = tuple(f for f in writer.picture_failures if f is not None)
    return FitRun(tuple(axes), unit, info, failures)


@contextlib.contextmanager
def column_warnings(column):
    """Warnings shown while one column is fitted start with its name (``gyro_x: sampler not
    converged ...``), as the command's own warnings of a column do: a several-column fit otherwise
    repeats one warning per column, none saying which. Each warning keeps its category and is shown
    as it is raised, through whatever ``warnings.showwarning`` shows it (a warning filtered to an
    error still raises)."""
    prefix = f"{column}: "
    with warnings.catch_warnings():
        shown = warnings.showwarning

        def show(message, category, filename, lineno, file=None, line=None):
            text = str(message)
            if not text.startswith(prefix):
                try:
                    message = category(prefix + text)
                except Exception:  # a category that takes other arguments: its text alone
                    message = prefix + text
            shown(message, category, filename, lineno, file, line)

        warnings.showwarning = show
        yield


def fit_job(job):
    """One log of a batch (:func:`run_fit_batch`'s default task): :func:`run_fit` of the job's
    request into its folder, its outputs written in this process; returns 0, or
    :data:`~bayes_imu.report.worker.PICTURE_FAILED_STATUS` where a picture was not drawn."""
    run = run_fit(job.request, job.out, background=False)
    return PICTURE_FAILED_STATUS if run.picture_failures else 0


def run_fit_batch(request, logs, out, *, task=fit_job, scheduler=None, n_workers=None, force=False,
                  progress=False):
    """Every log's own fit of ``request`` into ``out/<log name>/`` and ``out/batch.json``
    (``bayes-imu fit-batch``), each in a staged copy of ``out`` moved in whole.

    Parameters
    ----------
    request : FitRequest
        The fit of each log (its ``source.log`` replaced by each of ``logs``).
    logs : sequence of Path
    out : Path
    task : callable
        Module-level ``task(job)`` of a :class:`~bayes_imu.report.fleet.BatchJob` (Dask pickles
        it by reference): :func:`fit_job`, or a caller's wrapper of it.
    scheduler, n_workers, progress
        :func:`~bayes_imu.report.fleet.run_batch`'s.
    force : bool
        Replace a previous bayes_imu result in ``out``.

    Returns
    -------
    BatchRun
    """
    import time

    from .fleet import BatchJob, job_name, run_batch

    with staged_folder(out, force=force, inputs=logs) as staging:
        names, jobs = [], []
        for log in logs:
            names.append(job_name(log, names))
            source = dataclasses.replace(request.source, log=log)
            job_request = dataclasses.replace(request, source=source)
            jobs.append(BatchJob(names[-1], job_request, staging / names[-1]))
        start = time.perf_counter()
        results = run_batch(jobs, task, scheduler=scheduler, n_workers=n_workers,
                            progress=progress)
        seconds = time.perf_counter() - start
        doc = batch_summary(results, logs, staging, seconds=seconds, scheduler=scheduler,
                            seed=request.seed)
        write_json(staging / "batch.json", doc)
    return BatchRun(tuple(results), doc, seconds)


def run_allan(source, out, *, grid="octave", force=False, progress=False, on_read=None):
    """The Allan deviation of one column of ``source`` (a
    :class:`~bayes_imu.allan.pipeline.LogSource`) into ``out``: ``allan.csv`` and ``allan.png``
    (``bayes-imu allan``); ``on_read(read)`` as :func:`run_fit`'s.

    Returns
    -------
    AllanRun
    """
    from .plots import plot_allan

    read = allan_from_source(source, purpose="allan", grid=grid, progress=progress)
    columns, result, unit = read.columns, read.results[0], read.unit
    if on_read is not None:
        on_read(read)
    with staged_folder(out, force=force, inputs=input_files(source.log)) as tmp:
        write_allan_csv(result, tmp / "allan.csv", unit=unit)
        label = f"{Path(source.shown).name}: {columns[0]} [{unit}]"
        failure = draw_picture(plot_allan, result, tmp / "allan.png", label=label, unit=unit)
    return AllanRun(read, () if failure is None else (failure,))


def _fit_axis(request, allan, unit, info, column, folder, out, writer, *, progress, on_axis):
    from ..inference.archive import ARCHIVE_NAME, save_fit, write_netcdf
    from ..drift.display import display_parameters, rate_display
    from ..inference.fit import fit_allan
    from .plots import plot_allan_fit, plot_corner

    out.mkdir(exist_ok=True)
    # the output process seeks modes ahead while this process fits (fit_allan's pool; the same
    # numbers)
    result = fit_allan(allan, terms=request.terms, likelihood=request.likelihood, rng=request.seed,
                       discrepancy=request.discrepancy, progress=progress,
                       pool=writer.pool() if writer.background else None)
    # the figures first, the longer first: the output process draws one while this process
    # summarises and writes the rest, and the other beside it once this process waits
    # (report.worker). The corner plot of four or more parameters takes longer than
    # allan_fit.png (timings: docs/speed_under_load.md#figures)
    label = f"{Path(info['log']).name}: {column}"
    shown, scale = rate_display(unit, request.display_units)  # --display-units: figures too
    figures = [(plot_allan_fit, result, out / "allan_fit.png",
                {"label": label, "unit": shown, "rng": request.seed, "scale": scale}),
               (plot_corner, result, out / "corner.png", {"unit": shown, "scale": scale})]
    for plot, *arguments, options in (figures[::-1] if result.samples.shape[1] >= 4 else figures):
        writer.picture(plot, *arguments, **options)
    drift = drift_outputs(result, request, unit) if request.sensor else None
    summary = axis_summary(result, unit=unit, info=info, column=column, drift=drift)
    displayed = display_parameters(summary["parameters"], unit, request.display_units)
    if displayed is not None:  # beside the SI values
        summary["parameters_display"] = displayed
    checked = datasheet_summary(request, result, unit)
    if checked is not None:
        summary["datasheet_check"] = checked
    if drift is not None:
        write_drift(drift, out, submit=writer.submit)
    check = None
    if summary["adequacy"] is not None:
        summary["adequacy"]["drift"], check = drift_check_summary(result, request, unit, drift)
    axis = AxisRun(column, folder, result, summary, drift, check)
    if on_axis is not None:
        on_axis(axis)
    write_json(out / "summary.json", summary)
    save_fit(result, out / ARCHIVE_NAME)
    # posterior.nc here: it needs only h5netcdf (h5py is loaded with emcee), and queued behind
    # the figures it would end the run later
    write_netcdf(result, out / "posterior.nc")
    return axis


def datasheet_summary(request, result, unit):
    """``summary.json``'s ``datasheet_check`` of ``request.datasheet`` (``None`` without one):
    each datasheet value's posterior probability of being within spec, and the verdict line.

    Raises
    ------
    InputError
        A datasheet of another sensor kind than the fit's unit (or a fit not in SI).
    """
    given = request.datasheet
    if given is None:
        return None
    from ..noise.datasheet import KIND_OF_UNIT
    from ..noise.datasheet_check import check_datasheet, verdict

    path, kind, spec = given
    if KIND_OF_UNIT.get(unit) != kind:
        raise InputError(f"datasheet={path}: a {kind} datasheet, but the log is in {unit!r}; "
                         f"expected a {kind} log fitted in SI (give units)")
    values = check_datasheet(result, kind, spec)
    return {"file": str(path), "kind": kind, "values": values, "verdict": verdict(values)}


def run_population(request, logs, out, *, spread_scale=1.0, force=False, progress=False,
                   on_fit=None):
    """The hierarchical fit of one column of several units' ``logs`` into ``out``
    (``bayes-imu fit-population``): ``summary.json``, ``population.png`` and, with
    ``request.sensor``, the new unit's ``drift.csv`` and ``drift.png``.

    Parameters
    ----------
    request : FitRequest
        How to read each log (``request.source``, its ``log`` replaced by each of ``logs``), the
        terms, the seed and the drift options.
    logs : sequence of Path
        One log per unit (at least two, of distinct units).
    out : Path
    spread_scale : float
        Scale of the half-normal prior on the unit-to-unit spread of each ln-parameter.
    force, progress : bool
        As :func:`run_fit`.
    on_fit : callable, optional
        ``on_fit(run)`` with the :class:`PopulationRun` (no pictures yet) once its numbers are
        known, before the pictures are drawn.

    Returns
    -------
    PopulationRun
    """
    from ..drift.bands import drift_bands, integrated_unit
    from ..drift.display import display_parameters, display_unit, rate_display
    from ..inference.population import fit_population
    from ..inference.population_archive import save_population
    from .fleet import job_name
    from .plots import plot_population
    from .scene import distinct_units

    column = request.source.column
    if column is not None and "," in str(column):
        raise InputError(f"column={column!r}: fit-population takes one column (one axis of every "
                         "unit)")
    if len(logs) < 2:
        raise InputError(f"fit-population: {len(logs)} log given; expected the logs of at least "
                         "2 units")
    distinct_units(logs, where="fit-population")
    allans, labels, infos, unit = [], [], [], None
    for path in logs:
        read = allan_from_source(dataclasses.replace(request.source, log=path), purpose="fit",
                                 progress=progress)
        columns, unit, info = read.columns, read.unit, read.info
        allans.append(read.results[0])
        infos.append(info)
        labels.append(job_name(Path(info["log"]), labels))
    with staged_folder(out, force=force, inputs=logs) as tmp:
        pop = fit_population(allans, labels=labels, terms=request.terms, rng=request.seed,
                             spread_scale=spread_scale, progress=progress)
        drift = drift_outputs(pop.new_unit, request, unit) if request.sensor else None
        summary = population_summary(pop, unit=unit, column=columns[0], infos=infos, drift=drift)
        shown = display_parameters(summary["new_unit"], unit, request.display_units)
        if shown is not None:  # beside the SI values, as fit's parameters_display
            summary["new_unit_display"] = shown
        run = PopulationRun(pop, summary, drift)
        if on_fit is not None:
            on_fit(run)
        bands, unit_bands, drift_unit = None, (), None
        if drift is not None:  # the new unit's first quantity, as in drift.csv, against each unit's
            write_drift(drift, tmp)
            bands, drift_unit = drift.bands[0], drift.units[0]
            factor = display_unit(integrated_unit(unit, bands.quantity), request.display_units)[1]
            unit_bands = [drift_bands(f, bands.t_s, quantity=bands.quantity,
                                      bias_start=request.bias_start,
                                      calibration_s=request.calibration,
                                      rng=request.seed).scaled(factor)
                          for f in pop.unit_fits]
        write_json(tmp / "summary.json", summary)
        save_population(pop, tmp)  # report and export read it instead of fitting again
        rate_unit, scale = rate_display(unit, request.display_units)  # the Allan panel
        failure = draw_picture(plot_population, pop, tmp / "population.png", unit=rate_unit,
                               bands=bands, unit_bands=unit_bands, rng=request.seed,
                               drift_unit=drift_unit, scale=scale)
    failures = () if failure is None else (failure,)
    return dataclasses.replace(run, picture_failures=failures)
