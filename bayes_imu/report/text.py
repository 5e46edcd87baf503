"""Numbers as the outputs print them (console, figures, report.html)."""

__all__ = ["p_text", "outage_text", "number_text", "interval_digits", "interval_numbers",
           "interval_text", "spread_prior_note", "repeats", "as_given", "PLAIN_RANGE"]


def p_text(p):
    """``"= 0.012"``, or ``"< 1e-300"`` for a p-value below what double precision resolves (one
    that underflowed to 0): never a p of exactly 0; ``"> 0.99"`` for one below 1 that two digits
    would round to 1. Written after ``p``: ``f"p {p_text(p)}"``."""
    if p < 1e-300:
        return "< 1e-300"
    text = f"{p:.2g}"
    return "> 0.99" if p < 1.0 and float(text) >= 1.0 else f"= {text}"


#: magnitudes printed without an exponent (:func:`number_text`): from 1e-3 up to (not including) 1e5
PLAIN_RANGE = (1e-3, 1e5)


def number_text(value, digits=3):
    """``value`` to ``digits`` significant digits, trailing zeros kept (they are digits: ``0.340``,
    ``73.0``): plain for magnitudes in :data:`PLAIN_RANGE` (``105``, ``661``, ``1050``,
    ``0.00123``), exponent notation outside it (``2.76e-05``, ``2.29e+05``); ``0`` as ``"0"``.
    The value is rounded first, so that 99999.7 to 3 digits is ``1.00e+05`` and 0.0009996 is
    ``0.00100``."""
    import math

    if not math.isfinite(value):
        return f"{value}"
    if value == 0:
        return "0"
    digits = max(1, int(digits))
    rounded = float(f"{value:.{digits - 1}e}")
    if not PLAIN_RANGE[0] <= abs(rounded) < PLAIN_RANGE[1]:
        return f"{value:.{digits - 1}e}"
    decimals = max(0, digits - 1 - math.floor(math.log10(abs(rounded))))
    return f"{rounded:.{decimals}f}"


def interval_digits(median, low, high, most=5):
    """The significant digits an interval resolves: two more than the median over the interval's
    width has (at least 3, at most ``most``): a factor-of-eight interval gives 3 digits, a 1% one 4;
    a width that is not positive and finite gives ``most``."""
    import math

    width = high - low
    if math.isfinite(width) and width > 0 and median != 0 and math.isfinite(median):
        return min(most, max(3, math.ceil(math.log10(abs(median) / width)) + 2))
    return most


def interval_numbers(median, low, high, most=5):
    """``(median, low, high)`` as text, all three to the same significant digits, the ones the
    interval resolves (:func:`interval_digits`), by :func:`number_text`: a median and its interval
    at one precision (``"192"``, ``"59.0"``, ``"661"``)."""
    digits = interval_digits(median, low, high, most)
    return tuple(number_text(v, digits) for v in (median, low, high))


def interval_text(median, low, high, most=5):
    """``"median 0.789, 90% [0.550, 4.20]"``: a median and its interval to the significant digits
    the interval resolves (:func:`interval_numbers`); the separator after the median is ``", "``."""
    shown = interval_numbers(median, low, high, most)
    return f"median {shown[0]}, 90% [{shown[1]}, {shown[2]}]"


def repeats(given, shown):
    """Whether ``given`` (an amount as a scene wrote it: ``"10 m"``, ``"10m"``, ``"1e1 m"``) says
    what ``shown`` (the amount as printed beside it, ``"10 m"``) says: the same number and the same
    unit, so that quoting it as well would say one thing twice (``requirement 10 m (10 m)``);
    both read as a scene's amounts are (:func:`~bayes_imu.drift.display.amount_parts`)."""
    from ..drift.display import amount_parts

    said = amount_parts(given)
    return said is not None and said == amount_parts(shown)


def as_given(given, shown, form="({})"):
    """``" (1 deg)"``: ``given`` (the amount as the scene wrote it) in ``form``, after ``shown``
    (the amount as printed); ``""`` where there is none or it :func:`repeats` ``shown``."""
    if not given or repeats(given, shown):
        return ""
    return " " + form.format(given)


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
