"""Numbers as the outputs print them (console, figures, report.html)."""

__all__ = ["p_text", "outage_text"]


def p_text(p):
    """``"= 0.012"``, or ``"< 1e-300"`` for a p-value below what double precision resolves (one
    that underflowed to 0): never a p of exactly 0; ``"> 0.99"`` for one below 1 that two digits
    would round to 1. Written after ``p``: ``f"p {p_text(p)}"``."""
    if p < 1e-300:
        return "< 1e-300"
    text = f"{p:.2g}"
    return "> 0.99" if p < 1.0 and float(text) >= 1.0 else f"= {text}"


def outage_text(t):
    """``"416 s"``, or the search limit where the longest outage reached it (an outage length on
    the report's page and console)."""
    from .scene import MAX_SEARCH_S

    if t >= MAX_SEARCH_S:
        return f"{MAX_SEARCH_S:g} s or more (search limit)"
    return f"{t:.4g} s"
