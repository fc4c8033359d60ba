"""How the report writes numbers: significant digits, percentages, quantities with an SI prefix, intervals.

One set of helpers for ``report.md`` and ``report.html`` (and the sentences of
:mod:`~furuta_drake.diagnosis.report.narrative`), so both say the same figure the same way. ``None`` (a figure that
was not finite) is written ``n/a``.
"""

from __future__ import annotations

import math

MISSING = "n/a"
# Units whose leading symbol takes a milli or micro prefix: "N m" -> "mN m", "s" -> "ms", "rad" -> "mrad".
PREFIXED = ("N m", "N m s/rad", "N m/rad", "N m/rad^3", "s", "rad", "rad/s")
PREFIXES = ((1.0, ""), (1e-3, "m"), (1e-6, "µ"))


def number(value, digits: int = 4) -> str:
    """``value`` to ``digits`` significant digits, without an exponent between 1e-4 and 1e6."""
    if value is None:
        return MISSING
    value = float(value)
    if value == 0.0 or not math.isfinite(value):
        return f"{value:g}"
    if not 1e-4 <= abs(value) < 1e6:
        return f"{value:.{digits}g}"
    rounded = round(value, digits - 1 - math.floor(math.log10(abs(value))))
    text = f"{rounded:.{max(digits - 1 - math.floor(math.log10(abs(rounded))), 0)}f}"
    return text.rstrip("0").rstrip(".") if "." in text else text


def percent(share, digits: int = 0) -> str:
    """A share (0.853) as a percentage ("85 %"), one more digit within a percent of 100 % (never rounded up to
    it)."""
    if share is None:
        return MISSING
    share = float(share)
    if 0.99 < share < 1 and digits == 0:
        digits = 1 if share < 0.999 else 2
    return f"{100 * share:.{digits}f} %"


def scale_of(value, unit: str) -> tuple[float, str]:
    """(factor, prefixed unit) that writes ``value`` [unit] with 1 to 3 digits before the point."""
    if unit not in PREFIXED or value is None or value == 0:
        return 1.0, unit
    for factor, prefix in PREFIXES:
        if abs(value) >= factor:
            return factor, prefix + unit
    return PREFIXES[-1][0], PREFIXES[-1][1] + unit


def quantity(value, unit: str, digits: int = 2, interval=None) -> str:
    """``value`` [unit] with an SI prefix ("8.1 ms"), and its interval in the same unit when given
    ("8.1 ms (95 % interval 7.9 to 8.3 ms)"); a dimensionless unit ("-" or "") is left out."""
    if value is None:
        return MISSING
    factor, shown = scale_of(value, unit)
    suffix = f" {shown}" if shown not in ("", "-") else ""
    text = number(value / factor, digits) + suffix
    if interval is not None and len(interval) == 2 and None not in interval:
        low, high = ends(interval[0] / factor, interval[1] / factor, digits)
        text += f" (95 % interval {low} to {high}{suffix})"
    return text


def ends(low: float, high: float, digits: int = 2) -> tuple[str, str]:
    """An interval's ends with enough significant digits (from ``digits``, at most 5) that they differ."""
    while digits < 5 and number(low, digits) == number(high, digits):
        digits += 1
    return number(low, digits), number(high, digits)


def interval_text(interval, unit: str = "", digits: int = 3) -> str:
    """``low to high`` with units ("7.9 ms to 8.3 ms"), or '' without an interval."""
    if not interval or len(interval) != 2:
        return ""
    return f"{quantity(interval[0], unit, digits)} to {quantity(interval[1], unit, digits)}"


def seconds_range(start, end) -> str:
    """A time window "1.87-1.96 s"."""
    return f"{number(start, 4)}-{number(end, 4)} s"
