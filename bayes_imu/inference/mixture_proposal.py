"""A mixture of Student t's fitted to a pilot chain: the tempered ensemble's jump between regions.

Where a term is half resolved by the record, the posterior holds several regions (a term near
absent and another taking its place; a second bias or a random walk explaining the same part of
the curve). Within each, the tempered ensemble's walkers mix in a few steps; *between* them the
share of walkers moves only by the swaps from hotter temperatures, and the walkers' mean keeps an
autocorrelation time of hundreds to thousands of steps (400-1 780 on the real ADIS16405 imu4 and
imu5 accelerometer z logs, ``docs/speed_under_load.md``, sixteenth session).

An independence Metropolis-Hastings move (Tierney 1994, Ann. Statist. 22, 1701, sec 2.3.3) whose
proposal covers every region moves a walker between regions in one step, at the rate the
proposal's weights and the posterior's agree. The proposal is a mixture of multivariate Student
t's whose locations, shapes and weights are those of a Gaussian mixture fitted by expectation
maximisation (Dempster, Laird & Rubin 1977) to the cold draws of a pilot run, the number of
components chosen by BIC (Schwarz 1978), each shape :data:`MIXTURE_INFLATE` times the fitted
covariance (a t's covariance is ``df / (df - 2)`` times its shape: 2.5 times the fitted one) and
the tails heavy (:data:`MIXTURE_DF`) so that the proposal's support covers the posterior's beyond
what the pilot saw. The mixture is frozen before the chain that is kept starts (the pilot is
discarded), so the move is a fixed Metropolis-Hastings kernel and the chain's target is exactly
the posterior whatever the pilot found; a poor pilot costs only acceptance.
"""

from dataclasses import dataclass

import numpy as np

__all__ = [
    "MIXTURE_DF",
    "MIXTURE_INFLATE",
    "MIXTURE_MAX_COMPONENTS",
    "MIXTURE_FIT_DRAWS",
    "StudentMixture",
    "fit_student_mixture",
]

#: degrees of freedom of every component (tails heavier than the pilot's Gaussian fit)
MIXTURE_DF = 5.0
#: factor from each fitted component's covariance to its t's shape matrix (the pilot's spread
#: understates the tails')
MIXTURE_INFLATE = 1.5
#: the most components tried (BIC picks among 1 .. this many)
MIXTURE_MAX_COMPONENTS = 4
#: draws of the pilot used for the fit (a random subset where there are more)
MIXTURE_FIT_DRAWS = 4000
#: expectation-maximisation iterations at most per number of components
_EM_ITERATIONS = 200
#: floor on each component's covariance: this share of the pooled per-coordinate variance plus
#: the square of this share of the coordinate's scale (``scale`` of :func:`fit_student_mixture`:
#: the prior box's width in a fit), so that a coordinate the pilot never moved still has a shape
_FLOOR = 1.0e-4


@dataclass(frozen=True, eq=False)
class StudentMixture:
    """A mixture of multivariate Student t's of common degrees of freedom.

    Parameters
    ----------
    weights : ndarray, shape (k,)
        Component weights (positive, summing to 1 within 1e-5; normalised).
    locs : ndarray, shape (k, n)
        Component locations.
    shapes : ndarray, shape (k, n, n)
        Component shape matrices (positive definite).
    df : float
        Degrees of freedom.
    """

    weights: np.ndarray
    locs: np.ndarray
    shapes: np.ndarray
    df: float = MIXTURE_DF

    def __post_init__(self):
        w = np.asarray(self.weights, float)
        locs = np.atleast_2d(np.asarray(self.locs, float))
        k, n = locs.shape
        shapes = np.asarray(self.shapes, float).reshape(k, n, n)
        if w.shape != (k,) or np.any(w <= 0) or not np.isclose(w.sum(), 1.0):
            raise ValueError("mixture weights must be positive, one per component, summing to 1")
        chol = np.linalg.cholesky(shapes)  # raises LinAlgError unless positive definite
        w = w / w.sum()  # exactly 1: numpy's choice in draw() asks it within ~1e-8
        object.__setattr__(self, "weights", w)
        object.__setattr__(self, "locs", locs)
        object.__setattr__(self, "shapes", shapes)
        object.__setattr__(self, "_chol", chol)
        object.__setattr__(self, "_inv_chol", np.linalg.inv(chol))
        # log weight minus half the log determinant: the components' relative normalisation (the
        # t's own constant is the same for every component and dropped)
        log_det = 2.0 * np.log(np.diagonal(chol, axis1=1, axis2=2)).sum(axis=1)
        object.__setattr__(self, "_log_norm", np.log(w) - 0.5 * log_det)

    @property
    def n_components(self):
        return self.weights.size

    def draw(self, n, random):
        """``(n, dim)`` draws from ``random`` (a ``numpy.random.Generator``): a component by its
        weight, then a normal draw through its Cholesky factor divided by sqrt(chi2_df / df)."""
        n = int(n)
        k = random.choice(self.weights.size, size=n, p=self.weights)
        z = np.einsum("nij,nj->ni", self._chol[k], random.standard_normal((n, self.locs.shape[1])))
        return self.locs[k] + z / np.sqrt(random.chisquare(self.df, n) / self.df)[:, None]

    def log_density(self, x):
        """Log density at the rows of ``x`` ``(m, dim)``, up to a constant (the same for every
        point)."""
        diff = np.asarray(x, float)[:, None, :] - self.locs[None]  # (m, k, n)
        maha = np.square(np.einsum("kij,mkj->mki", self._inv_chol, diff)).sum(axis=-1)
        return _log_sum_exp(
            self._log_norm - 0.5 * (self.df + self.locs.shape[1]) * np.log1p(maha / self.df))


def fit_student_mixture(draws, rng, max_components=MIXTURE_MAX_COMPONENTS, scale=None,
                        n_draws=MIXTURE_FIT_DRAWS):
    """The proposal of :mod:`bayes_imu.inference.mixture_proposal` from pilot ``draws``.

    Parameters
    ----------
    draws : ndarray, shape (m, n)
        Pilot draws (at least ``n + 2`` rows; a random subset of ``n_draws`` of them where there
        are more).
    rng : numpy.random.Generator
        The subset, and the initial centres of expectation maximisation (k-means++ seeding,
        Arthur & Vassilvitskii 2007).
    max_components : int
        BIC chooses among 1 to this many Gaussian components (fewer where the draws are too few
        for more: ``n + 2`` per component); a component left with less than one draw's weight is
        dropped.
    scale : ndarray, shape (n,), optional
        Each coordinate's scale, for the covariance floor (the prior box's widths in a fit; by
        default the draws' largest magnitude, at least 1).
    n_draws : int
        The most draws fitted (a region of 1-2% of the draws gets its own component more often
        from more: a refit on a long chain uses twice the default).

    Returns
    -------
    StudentMixture
        The chosen Gaussian mixture's weights and locations, its covariances times
        :data:`MIXTURE_INFLATE` as shapes, :data:`MIXTURE_DF` degrees of freedom.
    """
    x = np.asarray(draws, float)
    if x.ndim != 2 or x.shape[0] < x.shape[1] + 2:
        raise ValueError("a mixture proposal needs a pilot of at least n_par + 2 draws")
    if x.shape[0] > n_draws:
        # a random subset: an even stride through (steps x walkers) rows would take a few walkers
        x = x[np.sort(rng.choice(x.shape[0], int(n_draws), replace=False))]
    if not np.all(np.isfinite(x)):
        raise ValueError("a mixture proposal needs finite pilot draws")
    scale = np.maximum(np.abs(x).max(axis=0), 1.0) if scale is None else np.asarray(scale, float)
    floor = np.diag(_FLOOR * np.var(x, axis=0) + np.square(_FLOOR * scale))
    best = None
    for k in range(1, int(max_components) + 1):
        if x.shape[0] < k * (x.shape[1] + 2):
            break
        fitted = _em(x, k, rng, floor)
        if best is None or fitted[3] < best[3]:
            best = fitted
    weights, locs, covs, _ = best
    keep = weights * x.shape[0] >= 1.0
    keep[np.argmax(weights)] = True
    return StudentMixture(weights[keep] / weights[keep].sum(), locs[keep],
                          MIXTURE_INFLATE * covs[keep], MIXTURE_DF)


def _em(x, k, rng, floor):
    """Gaussian mixture of ``k`` components by expectation maximisation: ``(weights, means,
    covariances, bic)``; every covariance at least ``floor`` (a diagonal matrix)."""
    m, n = x.shape
    means = _seed_centres(x, k, rng)
    covs = np.broadcast_to(np.cov(x.T).reshape(n, n) + floor, (k, n, n)).copy()
    weights = np.full(k, 1.0 / k)
    previous = -np.inf
    for _ in range(_EM_ITERATIONS):
        log_r = _log_gauss(x, means, covs) + np.log(weights)  # (m, k)
        total = _log_sum_exp(log_r)
        resp = np.exp(log_r - total[:, None])
        mass = resp.sum(axis=0) + 1e-300
        weights = np.maximum(mass / m, 1e-12)
        weights /= weights.sum()
        means = (resp.T @ x) / mass[:, None]
        for j in range(k):
            d = x - means[j]
            covs[j] = (resp[:, j, None] * d).T @ d / mass[j] + floor
        log_lik = float(total.sum())
        if log_lik - previous <= 1e-6 * m:
            break
        previous = log_lik
    # BIC at the parameters returned (the loop's likelihood is the previous iteration's)
    log_lik = float(_log_sum_exp(_log_gauss(x, means, covs) + np.log(weights)).sum())
    n_free = k * (n + n * (n + 1) / 2) + k - 1
    return weights, means, covs, -2.0 * log_lik + n_free * np.log(m)


def _seed_centres(x, k, rng):
    """k-means++ seeding: the first centre a random draw, each next one drawn with probability
    proportional to the squared distance (in the draws' standardised coordinates) to the
    nearest centre so far."""
    z = (x - x.mean(axis=0)) / (x.std(axis=0) + 1e-300)
    centres = [int(rng.integers(x.shape[0]))]
    dist = np.square(z - z[centres[0]]).sum(axis=1)
    for _ in range(1, k):
        p = dist / dist.sum() if dist.sum() > 0 else None
        centres.append(int(rng.choice(x.shape[0], p=p)))
        dist = np.minimum(dist, np.square(z - z[centres[-1]]).sum(axis=1))
    return x[centres].copy()


def _log_sum_exp(a):
    """``log(sum(exp(a), axis=1))`` of ``(m, k)`` ``a``, shifted by each row's largest (numpy:
    scipy.special.logsumexp agrees to ~1e-14 but takes ~5x as long on the jump move's 160 rows)."""
    top = a.max(axis=1)
    return top + np.log(np.exp(a - top[:, None]).sum(axis=1))


def _log_gauss(x, means, covs):
    """``(m, k)`` log normal densities of the rows of ``x`` under each component (the common
    ``-n/2 log 2 pi`` dropped)."""
    chol = np.linalg.cholesky(covs)
    inv = np.linalg.inv(chol)
    maha = np.square(np.einsum("kij,mkj->mki", inv, x[:, None, :] - means[None])).sum(axis=-1)
    return -0.5 * maha - np.log(np.diagonal(chol, axis1=1, axis2=2)).sum(axis=1)
