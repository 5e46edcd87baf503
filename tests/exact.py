"""Independent exact references for the integrated-noise variances.

Neither uses the package's closed forms: both propagate the covariance of the state
``(b, v, p)`` of the paper's recursion (eqs 12, 18, 24),

    b_k = A b_{k-1} + dt w_{k-1},  v_k = v_{k-1} + dt x_{k-1},  p_k = p_{k-1} + dt v_{k-1},

one step at a time in exact rational arithmetic (:func:`fraction_variance`), or by binary
splitting of the affine covariance map in 400-bit mpmath arithmetic
(:func:`mpmath_variance`, O(log k) steps, for k up to 3e9). Everything is in units of
``dt = 1`` and ``q = 1``; ``a = dt / tau`` enters exactly (the float value converted
without rounding).
"""

from fractions import Fraction

import mpmath as mp


def _transition(source, a, one):
    """Transition matrix F of the state (b, v, p) with dt = 1."""
    A = one - a
    if source == "white":  # slot 0 holds the fresh sample w_k (A = 0), which feeds v
        return [[0, 0, 0], [1, 1, 0], [0, 1, 1]]
    return [[A, 0, 0], [1, 1, 0], [0, 1, 1]]


def fraction_variance(source, order, k, a=0.0, *, initial_bias_variance=0):
    """Exact variance of state ``order`` (0 = b or w, 1 = v, 2 = p) after ``k`` steps.

    For ``source="white"`` the slot-0 state carries the fresh sample ``w_k`` (variance 1),
    so order 0 is the variance of ``w`` itself, 1 and 2 the single and double integral.
    """
    one = Fraction(1)
    a = Fraction(a)
    F = _transition(source, a, one)
    P = [[Fraction(0)] * 3 for _ in range(3)]
    if source == "white":
        P[0][0] = one  # w_0
    else:
        P[0][0] = Fraction(initial_bias_variance)
    for _ in range(k):
        FP = [[sum(F[i][m] * P[m][j] for m in range(3)) for j in range(3)] for i in range(3)]
        P = [[sum(FP[i][m] * F[j][m] for m in range(3)) for j in range(3)] for i in range(3)]
        P[0][0] += one  # new driving sample (dt w for GM, fresh w for white)
    # for white noise slot 0 holds w_k (variance 1); v_k and p_k use w_0 .. w_{k-1}
    return P[order][order]


def mpmath_variance(order, k, a, *, prec=400):
    """Gauss-Markov variance (dt = 1, q = 1) by binary splitting, exact to ~prec bits."""
    with mp.workprec(prec):
        A = 1 - mp.mpf(a)
        F = mp.matrix([[A, 0, 0], [1, 1, 0], [0, 1, 1]])
        Q = mp.matrix([[1, 0, 0], [0, 0, 0], [0, 0, 0]])

        def compose(first, second):
            (P1, S1), (P2, S2) = first, second
            return P2 * P1, P2 * S1 * P2.T + S2

        result, base, kk = (mp.eye(3), mp.zeros(3, 3)), (F, Q), int(k)
        while kk:
            if kk & 1:
                result = compose(result, base)
            base = compose(base, base)
            kk >>= 1
        return result[1][order, order]


def fraction_variance_dt(order, k, *, dt, tau, q=1):
    """Gauss-Markov variance of state ``order`` after ``k`` steps with an explicit time step,
    exactly.

    The paper's recursion with dt written out (no scaling argument): ``b_k = (1 - dt/tau) b_{k-1}
    + dt w_{k-1}`` with ``var(w) = q``, ``v_k = v_{k-1} + dt b_{k-1}``, ``p_k = p_{k-1} + dt
      v_{k-1}``;
    ``dt``, ``tau`` and ``q`` are converted to fractions without rounding.
    """
    dt, q = Fraction(dt), Fraction(q)
    A = 1 - dt / Fraction(tau)
    F = [[A, 0, 0], [dt, 1, 0], [0, dt, 1]]
    P = [[Fraction(0)] * 3 for _ in range(3)]
    for _ in range(k):
        FP = [[sum(F[i][m] * P[m][j] for m in range(3)) for j in range(3)] for i in range(3)]
        P = [[sum(FP[i][m] * F[j][m] for m in range(3)) for j in range(3)] for i in range(3)]
        P[0][0] += dt * dt * q
    return P[order][order]
