"""Stage 6, outputs: fits and drift bands in, files for people and tools out.

Owns the commands' whole runs from request objects (:mod:`~bayes_imu.report.runs`: a log's fit,
a batch, a population fit, an Allan deviation; :mod:`~bayes_imu.report.nav`), scene reports for
component selection (:mod:`~bayes_imu.report.scene`, HTML in
:mod:`~bayes_imu.report.html`), the figures (:mod:`~bayes_imu.report.plots`), the Kalibr file
(:mod:`~bayes_imu.report.kalibr`), batches of logs (:mod:`~bayes_imu.report.fleet`) and safe
writing of output folders (:mod:`~bayes_imu.report.output`). matplotlib is imported only
inside the functions that draw.
"""

from .scene import (
    Scene,
    SensorSpec,
    SensorReport,
    Report,
    read_scene,
    build_report,
    OUTPUT_UNITS,
)

__all__ = [
    "Scene",
    "SensorSpec",
    "SensorReport",
    "Report",
    "read_scene",
    "build_report",
    "OUTPUT_UNITS",
]
