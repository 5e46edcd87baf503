"""Kernel source of the io stage: the exact parser of plain delimited decimal tables.

Plain Python on numpy arrays, compiled ahead of time into ``bayes_imu._compiled`` by the build
(``setup.py``; strict IEEE arithmetic, no fast-math) and never JIT-compiled at run time: where the
extension lacks it, :mod:`bayes_imu.io.fastcsv` reads with numpy as before. This module imports
nothing but numpy, so that the build can load it alone.
"""

import numpy as np

__all__ = ["parse_table", "EXACT_POWERS"]

#: 10**0 .. 10**22, each exactly representable in float64 (5**22 < 2**53)
EXACT_POWERS = np.array([10.0**k for k in range(23)])
#: largest integer mantissa a double holds exactly
_MAX_MANTISSA = 2**53


def parse_table(buf, delimiter, n_columns, skip_first, wanted, out):
    """Parse a plain table of decimal numbers, keeping the columns ``wanted``.

    Parameters
    ----------
    buf : (n_bytes,) uint8
        The text (ASCII), lines ended by ``\\n`` or ``\\r\\n``; the last line may lack its end.
    delimiter : int
        The byte separating fields (``ord(",")``).
    n_columns : int
        Fields every data row must have.
    skip_first : int
        1: the first line is a header (skipped whatever it holds); 0: none.
    wanted : (k,) int64
        Columns to keep, 0-based, in the order of ``out``'s columns.
    out : (max_rows, k) float64
        Receives the rows.

    Returns
    -------
    int
        Rows written, or -1 where the text is not such a table or a field is not one this parser
        converts exactly (then nothing it wrote is to be used; the caller reads the file another
        way). Empty lines are skipped. A field is ``[+-]digits[.digits][(e|E)[+-]digits]`` (digits
        on at least one side of the point) whose significant digits form an integer ``M <= 2**53``
        and whose value is ``M * 10**e`` with ``|e| <= 22``: one correctly rounded product or
        quotient of two exact doubles, hence the correctly rounded value of the decimal, the same
        double as any correctly rounding reader gives (Clinger 1990, the exact fast path). Anything
        else (spaces, quotes, comments, ``nan``, more than 2**53 in the digits, a larger exponent,
        a row of another length, a byte-order mark without a header) returns -1.
    """
    n = buf.size
    max_rows = out.shape[0]
    slot = np.full(n_columns, -1, np.int64)
    for k in range(wanted.size):
        slot[wanted[k]] = k
    i = 0
    if skip_first:
        while i < n and buf[i] != 10:
            i += 1
        i += 1
    row = 0
    while i < n:
        c = buf[i]
        if c == 10:  # an empty line
            i += 1
            continue
        if c == 13:
            if i + 1 < n and buf[i + 1] == 10:
                i += 2
                continue
            return -1
        if row >= max_rows:
            return -1
        col = 0
        while True:
            # one field at i
            negative = False
            if i < n and (buf[i] == 45 or buf[i] == 43):
                negative = buf[i] == 45
                i += 1
            mantissa = 0
            significant = 0
            digits = 0
            exponent = 0
            point = False  # digits after the decimal point lower the exponent
            while i < n:
                if buf[i] == 46 and not point:
                    point = True
                    i += 1
                    continue
                if not 48 <= buf[i] <= 57:
                    break
                d = buf[i] - 48
                if significant > 0 or d > 0:
                    significant += 1
                    if significant > 18:
                        return -1
                    mantissa = mantissa * 10 + d
                if point:
                    exponent -= 1
                digits += 1
                i += 1
            if digits == 0:
                return -1
            if i < n and (buf[i] == 101 or buf[i] == 69):
                i += 1
                sign = 1
                if i < n and (buf[i] == 45 or buf[i] == 43):
                    if buf[i] == 45:
                        sign = -1
                    i += 1
                power = 0
                count = 0
                while i < n and 48 <= buf[i] <= 57:
                    power = power * 10 + (buf[i] - 48)
                    count += 1
                    if power > 400:
                        return -1
                    i += 1
                if count == 0:
                    return -1
                exponent += sign * power
            if mantissa == 0:
                value = 0.0
            elif mantissa > _MAX_MANTISSA or exponent > 22 or exponent < -22:
                return -1
            elif exponent >= 0:
                value = float(mantissa) * EXACT_POWERS[exponent]
            else:
                value = float(mantissa) / EXACT_POWERS[-exponent]
            if negative:
                value = -value
            if col >= n_columns:
                return -1
            if slot[col] >= 0:
                out[row, slot[col]] = value
            col += 1
            # what follows the field: the delimiter, or the end of the line
            if i < n and buf[i] == delimiter:
                i += 1
                continue
            if i >= n:
                break
            if buf[i] == 10:
                i += 1
                break
            if buf[i] == 13 and i + 1 < n and buf[i + 1] == 10:
                i += 2
                break
            return -1
        if col != n_columns:
            return -1
        row += 1
    return row
