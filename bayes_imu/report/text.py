"""Numbers as the outputs print them (console, figures, report.html)."""

__all__ = ["p_text"]


def p_text(p):
    """``"= 0.012"``, or ``"< 1e-300"`` for a p-value below what double precision resolves (one
    that underflowed to 0): never a p of exactly 0. Written after ``p``: ``f"p {p_text(p)}"``."""
    return f"= {p:.2g}" if p >= 1e-300 else "< 1e-300"
