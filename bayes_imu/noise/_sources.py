"""Source of the compiled Gauss-Markov AVAR kernel: plain Python that numba compiles twice.

Imported only to compile: :mod:`bayes_imu.noise.gauss_markov` JIT-compiles it on first use where
the package was built without its ahead-of-time build, which ``setup.py`` compiles into the
extension ``bayes_imu._compiled`` with the Allan-variance kernels (strict IEEE arithmetic in both:
the two builds give the same bits).
"""

__all__ = ["avar_rows"]


def avar_rows(mf, coeffs, s2, x, fx, e2, fy, switch, out):
    """``out[i, j]`` = AVAR at ``mf[j]`` of row ``i`` (``x = dt/T``, ``fx = 1 - e^-x``, ``e2 = 1 - e^-2x``,
    ``fy = 1 - e^-(m x)``): the exact series below ``m x = switch``, else the closed form."""
    n_terms = coeffs.shape[0]
    for i in range(x.size):
        ratio = x[i] / fx[i] if fx[i] > 0 else 1.0
        for j in range(mf.size):
            m = mf[j]
            y = m * x[i]
            if y <= switch:
                ys = -y
                poly = coeffs[n_terms - 1, j] * ys + coeffs[n_terms - 2, j]
                for k in range(n_terms - 3, -1, -1):
                    poly = poly * ys + coeffs[k, j]
                value = x[i] * ratio * ratio * poly / (m * m)
            else:
                value = (m * e2[i] - (1.0 - fx[i]) * fy[i, j] * (2.0 + fy[i, j])) / (m * m * fx[i] * fx[i])
            out[i, j] = s2[i] * value
