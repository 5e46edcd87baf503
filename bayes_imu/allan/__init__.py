"""Stage 2, the Allan variance: samples in, :class:`AllanResult` out.

Owns the overlapping estimator and its equivalent degrees of freedom and intervals
(:mod:`~bayes_imu.allan.estimator`), the segment Allan variances of the stationarity check,
the out-of-core pass over files larger than memory (:mod:`~bayes_imu.allan.outofcore`), the one
path from a log request to its Allan variances (:mod:`~bayes_imu.allan.pipeline`), Allan
tables written by other tools (:mod:`~bayes_imu.allan.table`), the autocorrelation fit
(:mod:`~bayes_imu.allan.autocorr`) and the compiled kernels (:mod:`~bayes_imu.allan.kernels`).
"""

from .estimator import (
    AllanResult,
    SegmentAllan,
    allan_variance,
    cluster_sizes,
    greenhall_edf,
    identify_noise,
    segment_allan,
    DEFAULT_SEGMENTS,
)

__all__ = [
    "AllanResult",
    "SegmentAllan",
    "allan_variance",
    "cluster_sizes",
    "greenhall_edf",
    "identify_noise",
    "segment_allan",
    "DEFAULT_SEGMENTS",
]
