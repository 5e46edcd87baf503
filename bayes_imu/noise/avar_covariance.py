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
(from a table of ``D``). Outside the overlap each term declares how it correlates
(:meth:`bayes_imu.noise.Term.covariance_tail`, one of :data:`~bayes_imu.noise._base.TAIL_KINDS`):
``"none"`` (white, quantization, filtered white, random walk, ramp), ``"gauss_markov"`` and
``"flicker"``, which the compiled kernel sums, ``"generic"``, for which every lag is summed
exactly from a table of ``D`` as long as the record (slower, :func:`exact_pair_sums`), or
``"deterministic"`` (a signal of fixed amplitude and random phase: its cross terms with the noise,
every lag, without its own fourth moments, :func:`exact_pair_sums`). A kind
outside that list, or a term that declares none, raises :class:`~bayes_imu.errors.ModelError`:
a correlation is never dropped in silence. In the kernel's tails: the Gauss-Markov part is exactly
geometric there (closed form per lag, no cancellation); the flicker part uses its asymptotic ``-h
a^2 b^2 / l_c^2`` (``l_c`` the distance between window centres; neglected terms ``O((b/l_c)^2)`` of
a tail below 1% of the total). Both tails are smooth, so they are summed by the midpoint rule with
steps of at most ``l_c/64`` and ``0.1 T/dt`` (relative error ~1e-4), which keeps a full covariance
of an octave grid on a long record cheap (timings: docs/speed_under_load.md#kernels).
"""

import numpy as np

from ..allan.kernels import avar_pair_sums
from ..errors import ModelError
from ._base import TAIL_KINDS
from .model import NoiseModel

__all__ = ["avar_covariance", "equivalent_dof", "exact_pair_sums", "model_tails"]


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
    tails = model_tails(model, params)
    kinds = {tail.kind for tail in tails}
    if "deterministic" in kinds or "generic" in kinds:
        lags = np.arange(n + 4 * ms.max() + 1)
        # D of the deterministic terms, of the terms correlated beyond the overlap window, and of
        # those that are not ("none": their c(l) is summed in the window only, as in the kernel)
        split = {"deterministic": 0.0, "long": 0.0, "none": 0.0}
        for term, tail in zip(model.components, tails):
            key = tail.kind if tail.kind in split else "long"
            split[key] = split[key] + term.structure(lags, params, model.dt)
        table, local, signal = (np.broadcast_to(np.asarray(split[k], dtype=float), lags.shape)
                                for k in ("long", "none", "deterministic"))
        sums = exact_pair_sums(table, ms, n, local=local,
                               deterministic=signal if "deterministic" in kinds else None)
    else:
        kmax = int(4 * ms.max() + 2)
        table = np.asarray(model.structure_function(np.arange(kmax + 1), params), dtype=float)
        h = sum(tail.flicker for tail in tails)
        gm = [c for tail in tails for c in tail.gauss_markov if c[0] > 0.0]
        s2 = np.array([c[0] for c in gm])
        x = np.array([c[1] for c in gm])
        sums = avar_pair_sums(table, ms, n, h, s2, x)
    mf = ms.astype(float)
    terms = (n - 2 * mf + 1).astype(float)
    norm = 2.0 * np.outer(mf * mf * terms, mf * mf * terms)
    cov = sums / norm
    return 0.5 * (cov + cov.T)


def model_tails(model, params):
    """The :class:`~bayes_imu.noise._base.CovarianceTail` of each term of ``model`` at ``params``,
    checked: :class:`~bayes_imu.errors.ModelError` for a kind the covariance code does not serve,
    or parts that do not match the kind."""
    tails = []
    for term in model.components:
        tail = term.covariance_tail(params, model.dt)
        kind = getattr(tail, "kind", None)
        if kind not in TAIL_KINDS:
            raise ModelError(f"term {term.name!r}: covariance tail kind {kind!r} is not one the "
                             f"AVAR covariance serves ({', '.join(TAIL_KINDS)})")
        stray_gm = tail.gauss_markov and kind != "gauss_markov"
        if stray_gm or (tail.flicker != 0.0 and kind != "flicker"):
            raise ModelError(f"term {term.name!r}: covariance tail of kind {kind!r} carries parts "
                             "of another kind")
        tails.append(tail)
    return tails


def exact_pair_sums(table, ms, n, *, deterministic=None, local=None):
    """``sum_l n(l) c(l)^2`` for every pair of cluster sizes, exactly over every lag of the record.

    The path of a term whose correlation beyond the overlap window has no kernel form (kind
    ``"generic"``): ``c(l)`` from the table of ``D`` at every lag where the two estimates share
    index pairs, ``-M_a < l < M_b``. ``table`` must reach ``n + 4 max(m)``.

    With ``deterministic``, the table of ``D`` of the terms of fixed amplitude and random phase
    (kind ``"deterministic"``, a vibration line), the sum is ``sum_l n(l) c(l) (c(l) + 2 e(l))``
    with ``e`` from that table: the noise's own part and its cross terms with the signal. The
    signal's own fourth moments are left out: the mean square of a fixed-amplitude sinusoid over
    the ``M`` second differences of one estimate varies with its phase only as ``O(1/M)`` (where
    a Gaussian process of the same covariance would give the estimate about two degrees of
    freedom).

    With ``local``, the table of ``D`` of terms whose second differences are uncorrelated
    beyond the overlap window (tail kind ``"none"``: white, random walk, ...), their ``c(l)`` is
    added in the window ``-2b <= l <= 2a`` only, from ``D`` at lags below ``4 max(m) + 1``, as
    the compiled kernel does. Taking their second differences at lags of the order of the record
    instead cancels catastrophically (a rate random walk's ``D(l) ~ l^3``): on 8.6e6 samples the
    variance of the estimate at one sample came out 470 times too large.

    Returns
    -------
    (n_tau, n_tau) ndarray
    """
    reach = n + 2 * int(ms.max())  # |pa - l| <= reach for every pair and lag
    k = ms.size
    out = np.zeros((k, k))
    spread = bool(np.any(table))  # any term correlated beyond the window
    kernel, fill = _pair_sum_kernel(), _kernels["second_differences_into"]
    top = table.size - 1
    lo, size = top - reach, 2 * reach + 1
    empty = np.zeros(0)
    # the tables reflected about lag 0 (ext[j + top] = D(|j|)), and one buffer each for their
    # second differences at every step b
    ext = np.concatenate([table[:0:-1], table]) if spread else None
    ext_h = None if deterministic is None else np.concatenate([deterministic[:0:-1], deterministic])
    g = np.empty(size) if spread else empty
    h = empty if ext_h is None else np.empty(size)
    for ib in range(k):
        b = int(ms[ib])
        mb = n - 2 * b + 1
        if spread:
            fill(ext, lo, b, g)  # g[j + reach] = sum_q w_q D(|j - q b|), |j| <= reach
        if ext_h is not None:
            fill(ext_h, lo, b, h)
        for ia in range(ib + 1):
            a = int(ms[ia])
            ma = n - 2 * a + 1
            half, w_lo = (empty, 0) if local is None else _window_covariance(local, a, b, ma, mb)
            out[ia, ib] = out[ib, ia] = kernel(g, h, half, w_lo, a, ma, mb, reach, int(spread),
                                               int(ext_h is not None))
    return out


_kernels = {}  # filled on first use (:func:`_pair_sum_kernel`)


def _pair_sum_kernel():
    """The compiled lag sum of one pair (:func:`bayes_imu.noise._sources.pair_sum_lags`) and the
    fill of second differences it reads: the numpy form they replaced made ~14 record-long
    temporaries per pair (3 s of a 10 s fit of a 1e6-sample ADIS16405 log with a vibration line;
    issue 39)."""
    if not _kernels:
        from ..allan.kernels import compiled_kernel

        for name in ("pair_sum_lags", "second_differences_into"):
            _kernels[name] = compiled_kernel(name, f"{__package__}._sources")
    return _kernels["pair_sum_lags"]


def _window_covariance(local, a, b, ma, mb):
    """``(half, offset)``: ``1/2 sum_{p,q} w_p w_q D(|p a - q b - l|)`` of the table ``local`` in
    the overlap window ``-2b <= l <= 2a`` (within the lags ``-(M_a - 1) .. M_b - 1``), which ``c``
    loses there, and the offset of its first lag."""
    lag = np.arange(max(-2 * b, -(ma - 1)), min(2 * a, mb - 1) + 1)
    part = np.zeros(lag.size)
    for p, wa in ((0, 1.0), (1, -2.0), (2, 1.0)):
        for q, wb in ((0, 1.0), (1, -2.0), (2, 1.0)):
            part += wa * wb * local[np.abs(p * a - q * b - lag)]
    return 0.5 * part, int(lag[0] + (ma - 1))


def equivalent_dof(avar, cov):
    """EDF ``2 AVAR^2 / Var`` of each estimate."""
    return 2.0 * np.asarray(avar) ** 2 / np.diag(cov)
