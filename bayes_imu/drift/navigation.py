"""The navigation channel: one horizontal channel of a free-inertial navigator in a GPS outage.

Error model (local-level frame, small angles, stationary or constant-velocity vehicle)::

    p' = v,   v' = -g phi + a_err,   phi' = v / R + w_err

with ``g`` = :data:`GRAVITY` (standard gravity, 9.80665 m/s^2) and ``R`` = :data:`EARTH_RADIUS`
(mean Earth radius, 6.371e6 m): the Schuler loop, ``w_s = sqrt(g/R)`` = 1.2407e-3 rad/s, period
84.4 min. ``schuler=False`` drops ``v/R`` (``w_s = 0``): the uncoupled short-term forms
(``g b t^3 / 6`` for a constant gyro bias ``b``, ``g N sqrt(t^5 / 20)`` for angle random walk).

Sampled noise (the same convention as the drift of :mod:`bayes_imu.noise._base`): the error of
sample ``i`` of a sensor, ``e_i = y_i - b_hat``, is held over ``[i dt, (i+1) dt)`` and the loop
is integrated exactly (zero-order hold). The tilt (from a gyro) and the velocity (from an
accelerometer) with the Schuler loop off are then exactly ``dt sum_{i<k} e_i``, the drift of
order 1; the position is the exact integral of that piecewise-linear velocity,
``dt^2 sum_{i<k} (k - i - 1/2) e_i``, where the Euler drift of order 2 has ``k - i - 1`` (the two
differ by ``dt v_k / 2``, below 1e-3 relative beyond a few hundred samples).

Everything is written with three functions of elapsed time, stable at ``w t -> 0`` (sinc and
series forms, no ``1 - cos`` cancellation)::

    S(t) = sin(w t)/w,   K(t) = (1 - cos w t)/w^2 = t^2 sinc(w t/2)^2 / 2,
    J(t) = (w t - sin w t)/w^3          (t, t^2/2, t^3/6 at w = 0)

The response to a unit constant input over ``[0, t]`` (the calibration residual's weight) is
``(w^2/g K, S, K)`` for an accelerometer and ``(S, -g K, -g J)`` for a gyro, in the order
(tilt, velocity, position); a one-sample step of the loop is ``Phi = exp(F dt)``.

Each noise term supplies its sampled output as a linear state-space system (``Term.nav_filter``:
``s_{i+1} = F s_i + G eps_i``, ``y_i = H s_i + D eps_i``, ``eps`` i.i.d. standard normal) and
:meth:`NavLoop.linear_variance` propagates the covariance of the loop augmented with that
system exactly, by binary powering (``O(log k)`` matrix products, vectorised over posterior
draws); the calibration window is a first phase whose accumulator is the bias estimate. The
flicker (bias-instability) term has no finite state: :meth:`NavLoop.increment_variance`
evaluates its exact quadratic form over the stationary rate increments by FFT.
"""

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError

__all__ = [
    "GRAVITY",
    "EARTH_RADIUS",
    "QUANTITIES",
    "QUANTITY_UNITS",
    "SENSORS",
    "NavLoop",
    "loop_functions",
    "schuler_period_s",
]

#: standard gravity [m/s^2]
GRAVITY = 9.80665
#: mean Earth radius [m]
EARTH_RADIUS = 6.371e6
#: navigation error quantities, in state order
QUANTITIES = ("tilt", "velocity", "position")
QUANTITY_UNITS = {"tilt": "rad", "velocity": "m/s", "position": "m"}
#: sensor kinds and the unit their fit must be in
SENSORS = {"gyro": "rad/s", "accel": "m/s^2"}
_J_SWITCH = 0.5  # |w t| below which J uses its series
_J_TERMS = 12  # 0.5^24 / 27! ~ 6e-36


def schuler_period_s(g=GRAVITY, radius=EARTH_RADIUS):
    """``2 pi sqrt(R/g)`` [s] (5064 s = 84.4 min with the defaults)."""
    return 2.0 * np.pi * np.sqrt(radius / g)


def loop_functions(w, t):
    """``S, K, J`` of the module docstring at times ``t`` [s] (broadcast) for ``w`` [rad/s] >= 0."""
    t = np.asarray(t, float)
    z = w * t
    s = t * np.sinc(z / np.pi)
    k = 0.5 * t * t * np.sinc(z / (2.0 * np.pi)) ** 2
    small = np.abs(z) < _J_SWITCH
    zs = z[small]  # the series only where it is used (a long grid's late times are not)
    series = np.zeros(zs.shape)
    for n in range(_J_TERMS, -1, -1):  # (z - sin z)/z^3 = sum_n (-1)^n z^(2n) / (2n+3)!
        series = series * (-zs * zs) + 1.0 / _factorial(2 * n + 3)
    zb = np.where(small, 1.0, z)
    ratio = np.array((zb - np.sin(zb)) / zb**3, dtype=float)  # a writable copy, 0-d too
    ratio[small] = series
    j = ratio * t**3
    return s, k, j


def _factorial(n):
    from math import factorial

    return float(factorial(n))


@dataclass(frozen=True)
class NavLoop:
    """One horizontal channel driven by one sensor's noise (module docstring).

    Attributes
    ----------
    sensor : {"gyro", "accel"}
        Which input the noise enters: a gyro (rad/s) about the perpendicular horizontal axis,
        or an accelerometer (m/s^2) along the channel.
    schuler : bool
        Schuler loop on (default) or off.
    g : float
        Gravity [m/s^2].
    radius : float
        Earth radius [m].
    """

    sensor: str
    schuler: bool = True
    g: float = GRAVITY
    radius: float = EARTH_RADIUS
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False, hash=False)

    def __post_init__(self):
        if self.sensor not in SENSORS:
            raise InputError(f"sensor={self.sensor!r}: expected one of {', '.join(SENSORS)}")

    @property
    def omega(self):
        """Schuler frequency ``sqrt(g/R)`` [rad/s], 0 with the loop off."""
        return float(np.sqrt(self.g / self.radius)) if self.schuler else 0.0

    def response(self, t):
        """``(3, ...)``: tilt, velocity, position after a unit constant input over ``[0, t]``."""
        w, g = self.omega, self.g
        s, k, j = loop_functions(w, t)
        if self.sensor == "accel":
            return np.stack([w * w / g * k, s, k])
        return np.stack([s, -g * k, -g * j])

    def transition(self, dt):
        """``(Phi, Gamma)``: the exact one-sample step ``x' = Phi x + Gamma e`` (3x3, 3)."""
        w, g = self.omega, self.g
        s, k, j = (float(v) for v in loop_functions(w, dt))
        c = np.cos(w * dt)
        phi = np.array([[c, w * w / g * s, 0.0], [-g * s, c, 0.0], [-g * k, s, 1.0]])
        return phi, self.response(dt).astype(float)

    def unit_variance(self, key, compute, k, dt, bias_start, n_cal):
        """``compute()`` memoised on ``(key, k, dt, bias_start, n_cal)``: a term's variance at unit
        amplitude does not depend on its parameters, so the candidate models of a model-averaged
        fit share it (a copy is returned)."""
        k = np.asarray(k, float)
        n_cal = np.asarray(n_cal, float)
        full = (key, k.tobytes(), float(dt), bias_start, n_cal.tobytes())
        if full not in self._cache:
            self._cache[full] = compute()
        return self._cache[full].copy()

    # --- finite-state terms --------------------------------------------------------------
    def linear_variance(self, filt, k, dt, *, bias_start="calibrated", n_cal=None):
        """Variance ``(..., n_t, 3)`` of (tilt, velocity, position) after ``k`` samples.

        Parameters
        ----------
        filt : dict
            The term's sampled output as a state-space system, arrays with batch shape ``...``:
            ``F (..., s, s)``, ``G (..., s, e)``, ``H (..., s)``, ``D (..., e)``, and the state
            covariance at the start, ``P_zero`` (``bias_start="zero"``), ``P_stationary``
            (``"stationary"``) and ``P_calibration`` (``"calibrated"``: at the start of the
            calibration window, ``n_cal`` samples before the outage).
        k : (n_t,) float
            Outage lengths in samples.
        dt : float
            Sample period [s].
        bias_start : {"zero", "stationary", "calibrated"}
        n_cal : int
            Calibration window in samples (``"calibrated"``).
        """
        f, gmat = np.asarray(filt["F"], float), np.asarray(filt["G"], float)
        h, d = np.asarray(filt["H"], float), np.asarray(filt["D"], float)
        batch = np.broadcast_shapes(f.shape[:-2], gmat.shape[:-2], h.shape[:-1], d.shape[:-1])
        ns, ne = f.shape[-1], gmat.shape[-1]
        dim = 3 + ns + 1
        phi, gam = self.transition(dt)
        a2 = np.zeros(batch + (dim, dim))
        b2 = np.zeros(batch + (dim, ne))
        a2[..., :3, :3] = phi
        a2[..., :3, 3 : 3 + ns] = gam[:, None] * h[..., None, :]
        a2[..., :3, -1] = -gam
        a2[..., 3 : 3 + ns, 3 : 3 + ns] = f
        a2[..., -1, -1] = 1.0
        b2[..., :3, :] = gam[:, None] * d[..., None, :]
        b2[..., 3 : 3 + ns, :] = gmat
        p0 = np.zeros(batch + (dim, dim))
        if bias_start == "calibrated":
            n_cal = int(n_cal)
            a1 = np.zeros(batch + (dim, dim))
            b1 = np.zeros(batch + (dim, ne))
            a1[..., 3 : 3 + ns, 3 : 3 + ns] = f
            a1[..., -1, 3 : 3 + ns] = h / n_cal
            a1[..., -1, -1] = 1.0
            b1[..., 3 : 3 + ns, :] = gmat
            b1[..., -1, :] = d / n_cal
            p0[..., 3 : 3 + ns, 3 : 3 + ns] = filt["P_calibration"]
            p0 = _propagate(a1, b1, p0, np.array([float(n_cal)]))[..., 0, :, :]
        else:
            p0[..., 3 : 3 + ns, 3 : 3 + ns] = filt[
                "P_zero" if bias_start == "zero" else "P_stationary"
            ]
        return np.maximum(_propagate_diagonal(a2, b2, p0, np.asarray(k, float), 3), 0.0)

    # --- flicker ------------------------------------------------------------------------
    def increment_tails(self, k, dt, n_cal, *, responses=None):
        """``(3, n_cal + k - 1)``: weights of the rate increments ``y_m - y_{m-1}``,
        ``m = -n_cal+1 .. k-1``, in the calibrated error (tilt, velocity, position).

        ``responses`` ``(3, >= k)``, optional: :meth:`response` at ``dt, 2 dt, ...`` (the same
        for every outage, computed once for the longest)."""
        k, n_cal = int(k), int(n_cal)
        if responses is None:
            responses = self.response(np.arange(1, k + 1, dtype=float) * dt)
        out = np.empty((3, n_cal + k - 1))
        # m < 0 (before the outage): the calibration's linear share of the full response
        before = np.arange(-n_cal + 1, 0, dtype=float)
        out[:, : n_cal - 1] = self.response(k * dt)[:, None] * (1.0 + before / n_cal)
        # 0 <= m < k: the response to the rest of the outage, (k - m) dt
        out[:, n_cal - 1 :] = responses[:, k - 1 :: -1]
        return out

    def increment_variance(self, k, dt, n_cal, acov):
        """Variance ``(n_t, 3)`` of the calibrated error of a process with stationary increments.

        ``acov(n)`` gives the autocovariance of the increments at lags ``0..n-1`` (unit
        amplitude; called once, for the longest outage and window, and sliced for the others). The
        quadratic form ``t' Gamma t`` over the increment weights (:meth:`increment_tails`) is
        exact; it is evaluated by FFT (circulant embedding, the form summed over the spectrum),
        whose rounding error is a few ``1e-16 n`` of ``gamma(0) |t|^2``.
        """
        # numpy's transform (the same pocketfft as scipy.fft's, the same bits) and the lengths
        # scipy.fft.next_fast_len gives real transforms: importing scipy.fft cost the command
        # about 0.25 s of its 1.4 s (docs/speed_under_load.md, seventeenth session)
        from ..inference.sampling import fft_length

        k = np.atleast_1d(np.asarray(k, float))
        n_cal = np.broadcast_to(np.asarray(n_cal, float), k.shape)
        out = np.zeros(k.shape + (3,))
        live = k >= 1
        if not live.any():
            return out
        # the response at dt, 2 dt, ... and the increments' autocovariance, each once
        k_max = int(k[live].max())
        responses = self.response(np.arange(1, k_max + 1, dtype=float) * dt)
        gamma_all = acov(int((n_cal[live].astype(np.int64) + k[live].astype(np.int64)).max()) - 1)
        for i, (ki, ni) in enumerate(zip(k, n_cal)):
            if ki < 1:
                continue
            tails = self.increment_tails(ki, dt, ni, responses=responses)
            n = tails.shape[1]
            size = fft_length(2 * n - 1)
            gamma = gamma_all[:n]
            # row 0: the circulant's first column (symmetric: its eigenvalues are real); rows 1-3:
            # the weights, zero past n; one batched transform of the four rows
            rows = np.zeros((1 + tails.shape[0], size))
            rows[0, :n] = gamma
            rows[0, size - n + 1 :] = gamma[1:][::-1]
            rows[1:, :n] = tails
            spectra = np.fft.rfft(rows, axis=1)
            # t' C t = sum_f |T_f|^2 lambda_f / size for the circulant C (eigenvalues lambda), and
            # t' C t = t' Gamma t for t zero past n: no inverse transform; the half spectrum counts
            # its inner frequencies twice
            spec = spectra[0].real
            spec[1 : (size + 1) // 2] *= 2.0
            tf = spectra[1:]
            power = tf.real * tf.real + tf.imag * tf.imag
            out[i] = np.maximum(power @ spec / size, 0.0)
        return out


_diagonal_kernel = None  # set on first use (:func:`_propagate_diagonal`)


def _propagate_diagonal(a, b, p0, k, n):
    """The first ``n`` diagonal entries ``(..., n_t, n)`` of :func:`_propagate`'s matrices: the
    compiled :func:`bayes_imu.noise._sources.propagate_diagonal` over the broadcast batch (the
    precompiled build's, else numba's JIT build), which carries only the ``n`` rows the diagonal
    needs through the binary powering: on a model-averaged pair's navigation bands (batches of up
    to 350 draws, 33 lengths to 2 h at 100 Hz) it took a fifth to a fourth of :func:`_propagate`'s
    time (docs/speed_under_load.md, fourteenth session)."""
    global _diagonal_kernel
    if _diagonal_kernel is None:
        from ..allan.kernels import compiled_kernel

        # nogil: the interpreter is free for the picture's import while it runs (report.nav; the
        # precompiled build's wrapper releases it too, setup.py)
        _diagonal_kernel = compiled_kernel("propagate_diagonal", "bayes_imu.noise._sources",
                                           nogil=True)
    a, b, p0 = (np.asarray(x, float) for x in (a, b, p0))
    kint = np.ascontiguousarray(np.asarray(k, float).astype(np.int64).ravel())
    d = a.shape[-1]
    if not 0 <= int(n) <= d:
        raise ValueError(f"n={n}: expected 0 to the state's {d} entries")
    q = b @ np.swapaxes(b, -1, -2)
    batch = np.broadcast_shapes(a.shape[:-2], q.shape[:-2], p0.shape[:-2])
    rows = [np.ascontiguousarray(np.broadcast_to(x, batch + (d, d)).reshape(-1, d, d))
            for x in (a, q, p0)]
    out = np.empty((rows[0].shape[0], kint.size, int(n)))
    _diagonal_kernel(*rows, kint, out)
    return out.reshape(batch + (kint.size, int(n)))


def _propagate(a, b, p0, k):
    """``A^k P0 A^k' + sum_{m<k} A^m B B' A^m'`` ``(..., n_t, d, d)`` by binary powering."""
    k = np.asarray(k, float)
    kint = k.astype(np.int64)
    q = b @ np.swapaxes(b, -1, -2)
    power, acc = a, q  # A^(2^j), S_(2^j)
    eye = np.broadcast_to(np.eye(a.shape[-1]), a.shape)
    res_a = np.repeat(eye[..., None, :, :], k.size, axis=-3)
    res_s = np.zeros(res_a.shape)
    top = int(kint.max()).bit_length() if k.size else 0
    for j in range(top):
        # only the lengths with this bit set move (about half of them): the products of the others
        # were computed and dropped before
        rows = np.flatnonzero((kint >> j) & 1)
        if rows.size:
            part = res_a[..., rows, :, :]
            res_s[..., rows, :, :] += part @ acc[..., None, :, :] @ np.swapaxes(part, -1, -2)
            res_a[..., rows, :, :] = part @ power[..., None, :, :]
        if j + 1 < top:
            acc = acc + power @ acc @ np.swapaxes(power, -1, -2)
            power = power @ power
    return res_a @ p0[..., None, :, :] @ np.swapaxes(res_a, -1, -2) + res_s
