"""The interface every noise term implements, and the exact drift contrasts they share.

A term is a stochastic (or, for the ramp, deterministic) component of the rate samples
``y_k`` at period ``dt``. Everything the package knows about it sits in its own module of
:mod:`bayes_imu.noise`, on one :class:`Term` object:

* ``avar(mf, params, dt)``: the exact expected overlapping Allan variance of sampled data at
  cluster sizes ``m`` (``tau = m dt``), broadcast ``(...,) x (n_tau,) -> (..., n_tau)``;
* ``avar_group`` and ``avar_many(others, mf, params, dt)`` (optional): terms of one group in a
  model evaluated in one call, each to the bits of its own ``avar`` (the Gauss-Markov terms);
* ``avar_power`` (optional): for a term of one parameter ``p`` whose Allan variance is
  ``p**avar_power`` times a curve of ``m`` alone (white noise, a random walk, ...), that power;
  a model then evaluates all such terms as one product with their curves
  (:class:`~bayes_imu.noise.model.AvarEvaluator`);
* ``structure(k, params, dt)``: the phase structure function ``D(k)`` (a generalised
  covariance of ``x_k = sum_{t<k} y_t``, in ``u^2``) from which the covariance of the AVAR
  estimates is built (:mod:`bayes_imu.noise.avar_covariance`);
* ``covariance_tail(params, dt)``: a :class:`CovarianceTail` saying how its correlation of
  second differences behaves beyond the overlap window of two AVAR estimates, one of
  :data:`TAIL_KINDS` (the covariance code refuses any other kind);
* ``simulate(params, n, dt, rng)``: an exact draw of the discrete process;
* ``drift_variance(order, k, params, dt, bias_start, n_cal)``: the exact variance (mean
  square) of its Euler-integrated error (attitude or velocity ``r = 1``, position ``r = 2``;
  any other order raises :class:`~bayes_imu.errors.ModelError`);
* ``bounds(scale)``: its prior box in log-parameters;
* ``starting_guess(tau, avar, m, dt)``: a rough value of each parameter read off an Allan
  variance curve, where the mode search of a fit starts;
* ``datasheet_rows(sensor)``: the rows it adds to a datasheet table
  (:func:`bayes_imu.noise.datasheet.datasheet`);
* ``kalibr``: what it is to Kalibr (:data:`KALIBR_ROLES`), with
  ``kalibr_random_walk2(draws, tau_max)`` for a ``"random_walk"`` term
  (:mod:`bayes_imu.report.kalibr`);
* ``selection``: its roles in the automatic model search (:data:`SELECTION_ROLES`) and
  ``requires``, the terms a model needs before it may have this one;
* ``start_variants(tau, avar, pilot=...)``: further starting values of some of its parameters,
  each tried as one more start of a fit's mode search (a Gauss-Markov bias: several time
  constants, since its posterior has a mode per bump of the curve);
* ``exchangeable``: a group name shared by terms that are the same process with one prior
  (two Gauss-Markov biases), which the sampler may relabel
  (:func:`bayes_imu.inference.fit.exchangeable_biases`);
* ``worst_axis``: its amplitude parameters (larger is a worse sensor at every averaging time)
  that a several-column ``summary.json`` reports as the worst axis
  (:func:`bayes_imu.report.writers.worst_axis`);
* ``parameter_labels``: what figures and tables call each parameter.

``tests/test_term_contract.py`` runs every term of the registry through one contract.

Drift semantics (``bias_start``), with the paper's Euler integral of ``e_i = y_i - b_hat``
(``v_k = dt sum_{i<k} e_i``, ``p_k = dt sum_{j<k} v_j``):

``"zero"``
    the process starts at zero at the outage (the paper), ``b_hat = 0``;
``"stationary"``
    a stationary process is in its stationary distribution, ``b_hat = 0``;
``"calibrated"``
    ``b_hat`` is the plain mean of the ``N`` samples just before the outage. The error is
    then a contrast of the phase record ``x`` that annihilates constants and linear trends,
    so its variance is ``-1/2 sum_pq a_p a_q D(|p - q|)`` for every term, random walk and
    flicker included (:func:`calibrated_contrast`).
"""

import threading
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from ..errors import InputError, ModelError

__all__ = ["Term", "PriorScale", "CovarianceTail", "calibrated_contrast", "check_order",
           "BIAS_STARTS", "ROLES", "ORDERS", "TAIL_KINDS", "SELECTION_ROLES", "KALIBR_ROLES",
           "DERIVED_PARAMETERS", "nav_system"]

#: drift semantics (see the module docstring)
BIAS_STARTS = ("zero", "stationary", "calibrated")
#: what a term means to a navigation engineer: short-term noise (sets the noise density),
#: a bias that wanders, or a slow drift of the rate
ROLES = ("short_term", "bias", "slow")
#: integration orders of the drift: 1 (attitude, velocity), 2 (position)
ORDERS = (1, 2)
#: how a term correlates second differences beyond the overlap window of two AVAR estimates:
#: not at all, geometrically (Gauss-Markov parts), as flicker (``~ lag^-2``), in a way only the
#: exact sum over every lag serves (a Gaussian process), or as a signal of fixed amplitude and
#: random phase (``"deterministic"``: only its cross terms with the noise spread the estimates,
#: summed over every lag; :func:`bayes_imu.noise.avar_covariance.avar_covariance`)
TAIL_KINDS = ("none", "gauss_markov", "flicker", "generic", "deterministic")
#: roles in the automatic model search (:mod:`bayes_imu.inference.selection`): always in the
#: model, in the exhaustive first round, or added by the stepwise search
SELECTION_ROLES = ("base", "optional", "extension")
#: what a term is to Kalibr (:mod:`bayes_imu.report.kalibr`): part of the white noise density,
#: part of the bias random walk, or left out (a deterministic or sub-sample term)
KALIBR_ROLES = ("noise_density", "random_walk", "none")
#: quantities a fit derives from its terms' parameters
#: (:meth:`bayes_imu.inference.fit.FitResult.draws`): the short-term white-equivalent density and
#: the white term's density alone [u/sqrt(Hz)]
DERIVED_PARAMETERS = ("noise_density", "white_noise_density")


def check_order(order):
    """``order`` if it is a supported integration order (:data:`ORDERS`), else ModelError."""
    if isinstance(order, bool) or order not in ORDERS:
        raise ModelError(f"integration order {order!r}: expected one of {ORDERS} "
                         "(1: attitude/velocity, 2: position)")
    return int(order)


@dataclass(frozen=True)
class CovarianceTail:
    """How one term correlates AVAR second differences beyond their overlap window.

    Attributes
    ----------
    kind : str
        One of :data:`TAIL_KINDS`.
    gauss_markov : tuple of (float, float)
        ``(sigma^2, dt/T)`` of each Gauss-Markov part (kind ``"gauss_markov"``).
    flicker : float
        ``h = B^2 / pi`` of a flicker part [u^2] (kind ``"flicker"``).
    """

    kind: str
    gauss_markov: tuple = ()
    flicker: float = 0.0


def calibrated_contrast(structure, order, k, n_cal, *, sums=None):
    """Variance of the calibrated-start error contrast, in phase units (multiply by ``dt**(2
    order)``).

    Parameters
    ----------
    structure : callable
        ``D(l)`` for an array of non-negative integer lags (scalar parameters).
    order : {1, 2}
    k : (n_t,) float
        Outage lengths in samples.
    n_cal : float or (n_t,) float
        Calibration window in samples (``>= 1``).
    sums : callable, optional
        ``sums(n) -> (D(n), F(n), G(n))`` for a Python ``int`` ``n >= 0``, exactly
        (``fractions.Fraction``) or in extended precision (``numpy.longdouble``). Used for
        order 2 when ``k + N`` exceeds :data:`TABLE_MAX` samples, where the table of ``D``
        would cost ``k + N`` evaluations and 48 bytes per sample (an outage of 1e6 s at
        100 Hz: 4.8 GB); without it, such a table is accumulated in blocks (bounded memory,
        the same sums bit for bit).

    Returns
    -------
    (n_t,) ndarray

    Raises
    ------
    ModelError
        For an order other than 1 or 2.

    Notes
    -----
    Order 1 (``v_k / dt = x_k - x_0 - (k/N)(x_0 - x_{-N})``, three phase points)::

        Var = (1 + r) D(k) - r D(k + N) + r (1 + r) D(N),   r = k / N

    Order 2 (``p_k / dt^2 = sum_{j<k} (x_j - x_0) - c (x_0 - x_{-N})``, ``c = k(k-1)/(2N)``,
    weights ``a_0 = -(k-1) - c``, ``a_j = 1`` for ``1 <= j < k``, ``a_{-N} = c``)::

        Var = -[G(k-2) + a_0 F(k-1) + c (F(N+k-1) - F(N)) + a_0 c D(N)]

    with ``F(n) = sum_{l=1}^n D(l)`` and ``G(n) = sum_{l=1}^n F(l)``, accumulated in
    extended precision from one table of ``D``.
    """
    order = check_order(order)
    k = np.asarray(k, dtype=float)
    n = np.broadcast_to(np.asarray(n_cal, dtype=float), k.shape)
    if order == 1:
        r = k / n
        out = (1.0 + r) * structure(k) - r * structure(k + n) + r * (1.0 + r) * structure(n)
        return np.where(k > 0, out, 0.0)
    top = int(np.max(k + n)) + 1 if k.size else 1
    if top > TABLE_MAX:
        if sums is not None:
            return _contrast_from_sums(sums, k, n)
        table, f, g = _blocked_sums(structure, top, np.concatenate([k - 2, k - 1, n + k - 1, n]))
    else:
        table = np.asarray(structure(np.arange(top + 1, dtype=float)), dtype=np.longdouble)
        f = np.cumsum(table)  # F(n) (D(0) = 0)
        g = np.cumsum(f)
    ki = k.astype(np.int64)
    ni = n.astype(np.int64)
    c = k * (k - 1.0) / (2.0 * n)
    a0 = -(k - 1.0) - c

    def at(arr, idx):
        return np.where(idx >= 0, arr[np.clip(idx, 0, None)], 0.0)

    out = -(
        at(g, ki - 2)
        + a0 * at(f, ki - 1)
        + c * (at(f, ni + ki - 1) - at(f, ni))
        + a0 * c * at(table, ni)
    )
    return np.where(k > 1, np.asarray(out, dtype=float), 0.0)


#: longest table of ``D`` (samples) that :func:`calibrated_contrast` builds whole
#: (2**20 samples: 48 MB of extended-precision sums)
TABLE_MAX = 2**20


def _contrast_from_sums(sums, k, n):
    """Order-2 contrast from exact or extended-precision ``D, F, G`` at the four points needed."""
    out = np.zeros(k.shape)
    for i, (kk, nn) in enumerate(zip(k.tolist(), n.tolist())):
        kk, nn = int(kk), int(nn)
        if kk <= 1:
            continue
        d_n, f_n, _ = sums(nn)
        f_k = sums(kk - 1)[1]
        g_k = sums(kk - 2)[2]
        f_nk = sums(nn + kk - 1)[1]
        c = Fraction(kk * (kk - 1), 2 * nn)
        if not isinstance(d_n, Fraction):  # extended precision: c rounded once
            c = np.longdouble(c.numerator) / np.longdouble(c.denominator)
        a0 = -(kk - 1) - c
        out[i] = float(-(g_k + a0 * f_k + c * (f_nk - f_n) + a0 * c * d_n))
    return out


def _blocked_sums(structure, top, wanted, block=TABLE_MAX):
    """``D, F, G`` at the indices ``wanted`` (others zero), summed in blocks of ``block`` samples.

    The running sums are carried into each block's first element before its ``cumsum``, so
    every value is the one a single ``cumsum`` over the whole table gives, bit for bit.
    """
    wanted = np.unique(wanted[(wanted >= 0) & (wanted <= top)].astype(np.int64))
    size = top + 1
    table, f, g = {}, {}, {}
    f_run = g_run = np.longdouble(0.0)
    for lo in range(0, size, block):
        hi = min(lo + block, size)
        d = np.asarray(structure(np.arange(lo, hi, dtype=float)), dtype=np.longdouble)
        fb = d.copy()
        fb[0] += f_run
        np.cumsum(fb, out=fb)
        gb = fb.copy()
        gb[0] += g_run
        np.cumsum(gb, out=gb)
        f_run, g_run = fb[-1], gb[-1]
        for j in wanted[(wanted >= lo) & (wanted < hi)].tolist():
            table[j], f[j], g[j] = d[j - lo], fb[j - lo], gb[j - lo]
    return _Sparse(table), _Sparse(f), _Sparse(g)


class _Sparse:
    """A few entries of a long array, read by an integer index array (others zero)."""

    def __init__(self, values):
        self.values = values

    def __getitem__(self, idx):
        idx = np.asarray(idx)
        return np.array([self.values.get(int(i), np.longdouble(0.0)) for i in idx.ravel()],
                        dtype=np.longdouble).reshape(idx.shape)


@dataclass(frozen=True)
class PriorScale:
    """What a term's prior box is scaled from: the observed Allan variance and the record.

    Attributes
    ----------
    log_lo, log_hi : float
        Natural logs of the lowest and highest Allan variance a term may reach over the
        fitted grid (``10**-4`` times the smallest, ``10**1`` times the largest observed).
    dt : float
        Sample period [s].
    tau_min, tau_max : float
        Shortest and longest fitted averaging times [s].
    m_min : float
        Smallest cluster size.
    record_s : float
        Duration of the record [s].
    """

    log_lo: float
    log_hi: float
    dt: float
    tau_min: float
    tau_max: float
    m_min: float
    record_s: float

    def amplitude(self, shift, power):
        """Box ``((lo + shift) power, (hi + shift) power)``: ``log(parameter) = power (log AVAR
        peak + shift)``."""
        return ((self.log_lo + shift) * power, (self.log_hi + shift) * power)


@dataclass(frozen=True)
class Term:
    """One noise term (see the module docstring for the interface).

    Attributes
    ----------
    name : str
    parameters : tuple of str
        Parameter names in sampling order.
    units : dict
        Parameter name -> unit template (``{u}`` is the rate unit).
    label : str
        IEEE Std 952 / navigation name.
    role : str
        One of :data:`ROLES`.
    selection : tuple of str
        Its roles in the automatic model search, from :data:`SELECTION_ROLES` (at least one).
    requires : tuple of str
        Terms a model must have to have this one (``gauss_markov_2`` needs ``gauss_markov``).
    kalibr : str
        One of :data:`KALIBR_ROLES`.
    short_label : str
        What figures call it (its :attr:`label` when empty).
    worst_axis : tuple of str
        Parameters reported as the worst axis of a several-column fit: amplitudes, whose larger
        value raises the Allan variance at every averaging time (not a time constant or a
        frequency, which have no worse direction), or :data:`DERIVED_PARAMETERS` of this term.
    exchangeable : str
        Group of terms that are one process with one prior box, parameters ``(variance, time
        constant)``, named apart only by the order of their time constants (empty: none).
    parameter_labels : dict
        Parameter name -> what figures and tables call it (the name itself where absent).
    """

    name: str
    parameters: tuple
    units: dict
    label: str
    role: str
    selection: tuple = ()
    requires: tuple = ()
    kalibr: str = ""
    short_label: str = ""
    worst_axis: tuple = ()
    exchangeable: str = ""
    parameter_labels: dict = None

    #: kind of :meth:`covariance_tail` (one of :data:`TAIL_KINDS`); a term whose tail carries
    #: parameters (Gauss-Markov, flicker) overrides :meth:`covariance_tail` as well
    tail_kind = None
    #: the bias start (:data:`BIAS_STARTS`) a record drawn by :meth:`simulate` realises at its
    #: first sample, or ``None`` for none (flicker has no start); the contract tests check the
    #: drift of that start by Monte Carlo
    simulated_start = None

    # --- interface, overridden by each term ---------------------------------------------
    def avar(self, mf, params, dt):  # pragma: no cover - abstract
        raise NotImplementedError

    #: terms of one model evaluated together by :meth:`avar_many` (``None``: each alone)
    avar_group = None

    #: ``k`` where the Allan variance is ``p**k`` times a curve of the cluster sizes alone, ``p``
    #: the term's one parameter (``None``: not of that form); checked by the contract suite
    avar_power = None

    def avar_many(self, others, mf, params, dt):
        """The Allan variances of this term and ``others`` (terms of its :attr:`avar_group` in one
        model), a list in that order, each bit for bit its own :meth:`avar`. By default each
        alone; a group overrides it where one call for all is cheaper (the Gauss-Markov terms:
        a model's fast correlated term and two biases in one compiled call, a likelihood call's
        largest part)."""
        return [t.avar(mf, params, dt) for t in (self, *others)]

    def structure(self, k, params, dt):  # pragma: no cover - abstract
        raise NotImplementedError

    def simulate(self, params, n, dt, rng):  # pragma: no cover - abstract
        raise NotImplementedError

    def bounds(self, scale):  # pragma: no cover - abstract
        raise NotImplementedError

    def starting_guess(self, tau, avar, m, dt):
        """Rough parameter values read off an Allan variance curve: dict name -> value.

        Parameters
        ----------
        tau, avar, m : (n_tau,) ndarray
            Averaging times [s], Allan variance [u^2] and cluster sizes of the curve.
        dt : float
            Sample period [s].
        """
        raise NotImplementedError(f"term {self.name!r} has no starting guess")  # pragma: no cover

    def start_variants(self, tau, avar, *, pilot):
        """Further starting values of some parameters: a tuple of dicts (name -> value), each
        replacing those values of :meth:`starting_guess` in one start of the mode search.

        Parameters
        ----------
        tau, avar : (n_tau,) ndarray
            Averaging times [s] and Allan variance [u^2] of the curve.
        pilot : bool
            Whether the search is a fit's first (no reference point from another model yet),
            which tries more starts.

        Returns
        -------
        tuple of dict
            ``({},)`` by default: the starting guess alone.
        """
        return ({},)

    def datasheet_rows(self, sensor):
        """Datasheet rows of this term for a sensor kind (``"gyro"`` or ``"accel"``, SI fits):
        dict row name -> ``(parameter, transform to the datasheet unit, unit, what it is)``."""
        raise NotImplementedError(f"term {self.name!r} has no datasheet rows")  # pragma: no cover

    def kalibr_random_walk2(self, draws, tau_max):
        """Squared bias random-walk density [u^2/s] per draw, for a term whose :attr:`kalibr` is
        ``"random_walk"``; ``draws``: parameter name -> ``(n_draws,)``, ``tau_max`` [s] the
        longest averaging time of the log."""
        raise NotImplementedError(  # pragma: no cover
            f"term {self.name!r} has no Kalibr random walk")

    def covariance_tail(self, params, dt):
        """:class:`CovarianceTail` of this term at one parameter point (scalars)."""
        if self.tail_kind in ("none", "generic", "deterministic"):
            return CovarianceTail(self.tail_kind)
        raise ModelError(f"term {self.name!r} declares no supported covariance tail "
                         f"(tail_kind={self.tail_kind!r}, expected one of {TAIL_KINDS})")

    def drift_variance(self, order, k, params, dt, *, bias_start="zero", n_cal=None):
        """Mean-square drift ``(..., n_t)`` [u^2 s^(2 order)] for parameters ``(...)`` and steps
        ``k`` ``(n_t,)``.

        Parameters
        ----------
        order : {1, 2}
            Integration order (1: attitude / velocity, 2: position); any other raises
            :class:`~bayes_imu.errors.ModelError`.
        k : (n_t,) float
            Outage lengths in samples.
        params : dict
            Parameter name -> ``(...)``.
        dt : float
            Sample period [s].
        bias_start : {"zero", "stationary", "calibrated"}
        n_cal : float or (n_t,) float
            Calibration window in samples (``bias_start="calibrated"``).
        """
        order = check_order(order)
        if bias_start not in BIAS_STARTS:
            raise InputError(f"bias_start={bias_start!r}: expected one of {', '.join(BIAS_STARTS)}")
        if bias_start == "calibrated" and n_cal is None:
            raise InputError("bias_start='calibrated' needs n_cal, the calibration window in "
                             "samples")
        return self._drift_variance(order, k, params, dt, bias_start, n_cal)

    def _drift_variance(self, order, k, params, dt, bias_start, n_cal):
        """:meth:`drift_variance` after its checks. The default serves terms whose drift is
        linear in one squared amplitude (:meth:`unit_drift`)."""
        amplitude = self.amplitude2(params)
        unit = self.cached_unit_drift(order, k, dt, bias_start, n_cal)
        return np.asarray(amplitude, float)[..., None] * unit

    def cached_unit_drift(self, order, k, dt, bias_start, n_cal):
        """:meth:`unit_drift`, remembered (a read-only array): it depends on no parameter, and a
        report asks for the same times once per model of the mixture and per search step."""
        k = np.asarray(k, dtype=float)
        n = None if n_cal is None else np.asarray(n_cal, dtype=float)
        key = (type(self), self.name, order, k.shape, k.tobytes(), float(dt), bias_start,
               None if n is None else (n.shape, n.tobytes()))
        return _unit_drift_cache(self, key)

    #: ``structure_sums(n, dt) -> (D(n), F(n), G(n))`` at unit squared amplitude for an ``int``
    #: ``n`` (``F(n) = sum_{l<=n} D(l)``, ``G(n) = sum_{l<=n} F(l)``), exact or in extended
    #: precision, for the order-2 contrast of long outages (:func:`calibrated_contrast`);
    #: ``None`` where a term has no closed form (the contrast then sums a table in blocks)
    structure_sums = None

    # --- helpers of terms linear in a squared amplitude ---------------------------------
    def amplitude2(self, params):
        """The squared amplitude the drift is proportional to."""
        raise NotImplementedError  # pragma: no cover

    def unit_drift(self, order, k, dt, bias_start, n_cal):
        """Drift variance at unit squared amplitude ``(n_t,)``; default: the calibrated contrast."""
        unit = {p: 1.0 for p in self.parameters}
        sums = None if self.structure_sums is None else (lambda n: self.structure_sums(n, dt))
        return dt ** (2 * order) * calibrated_contrast(
            lambda lag: self.structure(lag, unit, dt) / self.amplitude2(unit),
            order,
            k,
            n_cal,
            sums=sums,
        )

    @property
    def plot_label(self):
        """What figures call it: :attr:`short_label`, else :attr:`label`."""
        return self.short_label or self.label

    def parameter_label(self, name):
        """What figures and tables call parameter ``name`` (:attr:`parameter_labels`)."""
        return (self.parameter_labels or {}).get(name, name)

    def parameter_units(self, unit):
        return {p: self.units[p].format(u=unit) for p in self.parameters}

    # --- navigation channel (:mod:`bayes_imu.drift.navigation`) --------------------------
    def nav_filter(self, params, dt, *, n_cal=None):  # pragma: no cover - abstract
        """The sampled output as a linear state-space system driven by i.i.d. standard normals.

        ``s_{i+1} = F s_i + G eps_i``, ``y_i = H s_i + D eps_i``; a dict of ``F (..., s, s)``,
        ``G (..., s, e)``, ``H (..., s)``, ``D (..., e)`` and the state covariances at the
        start: ``P_zero``, ``P_stationary`` (at the outage) and ``P_calibration`` (``n_cal``
        samples before it), with the same semantics as :meth:`drift_variance`.
        """
        raise NotImplementedError

    def nav_variance(self, loop, k, params, dt, *, bias_start="calibrated", n_cal=None):
        """Variance ``(..., n_t, 3)`` of (tilt [rad^2], velocity [(m/s)^2], position [m^2]) of
        a navigation channel (``loop``, a :class:`bayes_imu.drift.navigation.NavLoop`) driven by
        this term after ``k`` ``(n_t,)`` samples; ``n_cal`` is the calibration window in samples.

        The default serves terms linear in one squared amplitude: the exact propagation of
        :meth:`nav_filter` at unit amplitude, scaled.
        """
        unit = {p: 1.0 for p in self.parameters}

        def compute():
            system = self.nav_filter(unit, dt, n_cal=n_cal)
            return loop.linear_variance(system, k, dt, bias_start=bias_start, n_cal=n_cal)

        v = loop.unit_variance(self.name, compute, k, dt, bias_start, n_cal)
        return np.asarray(self.amplitude2(params), float)[..., None, None] * v


def nav_system(f, g, h, d, p_zero, p_stationary=None, p_calibration=None):
    """The dict :meth:`Term.nav_filter` returns (start covariances default to ``p_zero``)."""
    p_stationary = p_zero if p_stationary is None else p_stationary
    p_calibration = p_stationary if p_calibration is None else p_calibration
    arrays = (f, g, h, d, p_zero, p_stationary, p_calibration)
    keys = ("F", "G", "H", "D", "P_zero", "P_stationary", "P_calibration")
    return {key: np.asarray(value, float) for key, value in zip(keys, arrays)}


#: remembered unit drifts: key -> (term, read-only array); the oldest is dropped beyond the limit
_UNIT_DRIFTS = {}
_UNIT_DRIFTS_MAX = 512
_UNIT_DRIFTS_LOCK = threading.Lock()  # drift bands may be computed on several threads


def _unit_drift_cache(term, key):
    hit = _UNIT_DRIFTS.get(key)
    if hit is not None and hit[0] is term:
        return hit[1]
    _, _, order, k_shape, k_bytes, dt, bias_start, n_key = key
    k = np.frombuffer(k_bytes, dtype=float).reshape(k_shape).copy()
    n_cal = None if n_key is None else np.frombuffer(n_key[1], dtype=float).reshape(n_key[0]).copy()
    out = np.array(term.unit_drift(order, k, dt, bias_start, n_cal), dtype=float)
    out.setflags(write=False)
    with _UNIT_DRIFTS_LOCK:
        if len(_UNIT_DRIFTS) >= _UNIT_DRIFTS_MAX:
            _UNIT_DRIFTS.pop(next(iter(_UNIT_DRIFTS)))
        _UNIT_DRIFTS[key] = (term, out)
    return out
