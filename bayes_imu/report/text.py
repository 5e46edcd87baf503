"""Numbers as the outputs print them (console, figures, report.html)."""

__all__ = ["p_text", "outage_text", "interval_digits", "interval_text", "spread_prior_note"]


def p_text(p):
    """``"= 0.012"``, or ``"< 1e-300"`` for a p-value below what double precision resolves (one
    that underflowed to 0): never a p of exactly 0; ``"> 0.99"`` for one below 1 that two digits
    would round to 1. Written after ``p``: ``f"p {p_text(p)}"``."""
    if p < 1e-300:
        return "< 1e-300"
    text = f"{p:.2g}"
    return "> 0.99" if p < 1.0 and float(text) >= 1.0 else f"= {text}"


def interval_digits(median, low, high, most=5):
    """The significant digits an interval resolves: two more than the median over the interval's
    width has (at least 2, at most ``most``): a factor-of-eight interval gives 2 digits, a 1% one 4;
    a width that is not positive and finite gives ``most``."""
    import math

    width = high - low
    if math.isfinite(width) and width > 0 and median != 0 and math.isfinite(median):
        return min(most, max(2, math.ceil(math.log10(abs(median) / width)) + 2))
    return most


def interval_text(median, low, high, most=5):
    """``"median 0.79, 90% [0.55, 4.2]"``: a median and its interval to the significant digits the
    interval resolves (:func:`interval_digits`); the separator after the median is ``", "``."""
    digits = interval_digits(median, low, high, most)
    return f"median {median:.{digits}g}, 90% [{low:.{digits}g}, {high:.{digits}g}]"


def outage_text(t):
    """``"416 s"``, or the search limit where the longest outage reached it (an outage length on
    the report's page and console)."""
    from .scene import MAX_SEARCH_S

    if t >= MAX_SEARCH_S:
        return f"{MAX_SEARCH_S:g} s or more (search limit)"
    return f"{t:.4g} s"


def spread_prior_note(pop):
    """A line where a population fit's unit-to-unit spread of some parameter is mostly its prior's
    (:meth:`~bayes_imu.inference.population.PopulationResult.spread_prior_share` at or above
    :data:`~bayes_imu.inference.population.SPREAD_PRIOR_SHARE`), else ``None``: the command's
    warning and the report's note."""
    from ..inference.population import SPREAD_PRIOR_SHARE

    share = pop.spread_prior_share()
    weak = {name: value for name, value in share.items() if value >= SPREAD_PRIOR_SHARE}
    if not weak:
        return None
    return (f"{len(pop.labels)} units barely measure the unit-to-unit spread of "
            f"{', '.join(weak)} (posterior standard deviation "
            f"{', '.join(f'{v:.2f}' for v in weak.values())} of the prior's): a new unit's bounds "
            f"lean on the spread's prior (half-normal, scale {pop.spread_scale:g} in ln units); "
            "more units measure it")
