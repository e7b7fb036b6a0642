"""Reading back the measurements the command prints, and checking the rounding rule on them.

The rule (Particle Data Group, as the issue states it): the uncertainty to two significant
digits, the value to the same decimal place, one notation for both (a shared power of ten in
parentheses, ``(5.36 ± 0.52)e3``). Checked here from the printed text and the unrounded
numbers alone, without the code that formats them.
"""

import math
import re

MEASUREMENT = re.compile(r"^(?P<open>\()?(?P<value>-?\d+(?:\.\d+)?) ± (?P<error>\d+(?:\.\d+)?)"
                         r"(?(open)\)e(?P<exponent>-?\d+))(?: (?P<unit>\S+))?$")


def decimals(number):
    """Digits after the decimal point of a printed number."""
    return len(number.split(".")[1]) if "." in number else 0


def check_measurement(text, value, stderr, unit=None):
    """Assert that `text` ("x ± y unit" or "(x ± y)eN unit") is `value` ± `stderr` rounded.

    Returns the printed value and uncertainty as floats (in the unit printed).
    """
    match = MEASUREMENT.match(text)
    assert match, f"not a measurement in one notation: {text!r}"
    if unit is not None:
        assert (match["unit"] or "") == unit, text
    exponent = int(match["exponent"] or 0)
    assert not match["exponent"] or not match["exponent"].startswith(("+", "0")), text
    places = decimals(match["value"])
    assert decimals(match["error"]) == places, f"value and error not to one place: {text!r}"
    unit_in_last_place = 10.0 ** (exponent - places)
    shown_value = float(match["value"]) * 10.0 ** exponent
    shown_error = float(match["error"]) * 10.0 ** exponent
    # Two significant digits of the error: 10 to 99 units in the last place (100 where
    # 99.5 rounds up, as 0.0996 -> 0.10).
    assert 10 <= round(shown_error / unit_in_last_place) <= 100, text
    tolerance = 0.5 * unit_in_last_place * (1 + 1e-9)
    assert abs(shown_error - stderr) <= tolerance, (text, stderr)
    assert abs(shown_value - value) <= tolerance, (text, value)
    return shown_value, shown_error


def measurement_of(line, symbol):
    """The measurement text after ``symbol = `` on a printed line, up to the next ", "."""
    match = re.search(rf"(?:^|, |: ){re.escape(symbol)} = (.+?)(?:, |$)", line)
    assert match, f"no {symbol} = on {line!r}"
    return match.group(1)


def close_to_bound(printed, bound):
    """True if a bound printed to three significant digits is `bound`."""
    return math.isclose(float(printed), float(f"{bound:.3g}"), rel_tol=1e-12)
