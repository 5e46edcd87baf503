"""Covariance of overlapping Allan variance estimates under a noise model (Gaussian fourth moments).

For rate samples ``y_0..y_{N-1}`` with phase ``x_k = sum_{t<k} y_t`` the overlapping
estimator at cluster size ``m`` (SP1065 eq 14) is
``avar(m) = sum_i d_i^2 / (2 m^2 M)``, ``d_i = x_{i+2m} - 2 x_{i+m} + x_i``,
``M = N - 2m + 1``. For a Gaussian process (Isserlis)::

    Cov(avar(a), avar(b)) = sum_l n(l) c(l)^2 / (2 a^2 b^2 M_a M_b)

where ``c(l) = Cov(d^a_i, d^b_{i+l}) = -1/2 sum_{p,q} a_p b_q D(|p - q - l|)`` from the
model's phase structure function ``D`` (:func:`bayes_imu.noise.avar_forms.structure_function`) and
``n(l)`` counts the index pairs at lag ``l``. Its diagonal gives the equivalent degrees of
freedom ``2 AVAR^2 / Var``, which for pure power-law noise is Greenhall & Riley's EDF
(the tests check this) and for a model with several terms is the exact generalisation.

The sum runs exactly over every lag where the two second-difference windows overlap or touch
(from a table of ``D``). Outside the overlap only the Gauss-Markov and flicker terms
correlate: the Gauss-Markov part is exactly geometric there (closed form per lag, no
cancellation); the flicker part uses its asymptotic ``-h a^2 b^2 / l_c^2`` (``l_c`` the
distance between window centres; neglected terms ``O((b/l_c)^2)`` of a tail below 1% of
the total). Both tails are smooth, so they are summed by the midpoint rule with steps of
at most ``l_c/64`` and ``0.1 T/dt`` (relative error ~1e-4), which keeps a full covariance
of an octave grid on 1e6 samples at ~0.1 s.
"""

import numpy as np

from ..allan.kernels import avar_pair_sums
from ..noise import NoiseModel

__all__ = ["avar_covariance", "equivalent_dof"]


def avar_covariance(model, params, m, n_samples):
    """Covariance matrix of the overlapping AVAR estimates at cluster sizes ``m``.

    Parameters
    ----------
    model : NoiseModel
    params : dict of float
        One parameter point (scalars).
    m : (n_tau,) int
        Cluster sizes, each ``<= (n_samples - 1) // 2``.
    n_samples : int
        Record length N (rate samples).

    Returns
    -------
    (n_tau, n_tau) ndarray
        Covariance of the AVAR estimates [u^4].
    """
    if not isinstance(model, NoiseModel):
        raise TypeError("model must be a NoiseModel")
    ms = np.asarray(m, dtype=np.int64)
    n = int(n_samples)
    kmax = int(4 * ms.max() + 2)
    table = np.asarray(model.structure_function(np.arange(kmax + 1), params), dtype=float)
    h = sum(t.flicker_level(params) for t in model.components)
    gm = [c for t in model.components for c in t.gm_components(params, model.dt) if c[0] > 0.0]
    s2 = np.array([c[0] for c in gm])
    x = np.array([c[1] for c in gm])
    sums = avar_pair_sums(table, ms, n, h, s2, x)
    mf = ms.astype(float)
    terms = (n - 2 * mf + 1).astype(float)
    norm = 2.0 * np.outer(mf * mf * terms, mf * mf * terms)
    cov = sums / norm
    return 0.5 * (cov + cov.T)


def equivalent_dof(avar, cov):
    """EDF ``2 AVAR^2 / Var`` of each estimate."""
    return 2.0 * np.asarray(avar) ** 2 / np.diag(cov)
