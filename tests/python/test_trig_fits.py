"""src/trig.hpp's coefficients and constants are those scripts/trig_fits.py computes: the
fit regenerated with mpmath and compared, double for double, with the header's polynomial
(read from its C++ as a polynomial in z) and atan2's reduction constants."""

import importlib.util
import re
from pathlib import Path

import pytest
from numpy.polynomial import Polynomial

ROOT = Path(__file__).resolve().parents[2]
HEADER = (ROOT / "src" / "trig.hpp").read_text()


@pytest.fixture(scope="module")
def fits():
    spec = importlib.util.spec_from_file_location("trig_fits", ROOT / "scripts" / "trig_fits.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def body(name):
    """The body of the header's function `name` (between its outer braces)."""
    start = HEADER.index("{", re.search(rf"\b{name}\(", HEADER).start())
    depth = 0
    for i in range(start, len(HEADER)):
        depth += {"{": 1, "}": -1}.get(HEADER[i], 0)
        if depth == 0:
            return HEADER[start + 1 : i]
    raise AssertionError(f"{name}: no closing brace")


def statements(text):
    """`name = expression` of each `const double` declaration, and a return's expression."""
    text = re.sub(r"//[^\n]*", "", text)
    out = {}
    for stmt in text.split(";"):
        stmt = " ".join(stmt.split())
        if stmt.startswith("const double "):
            for decl in stmt[len("const double ") :].split(", "):
                name, expr = decl.split(" = ", 1)
                out[name] = expr
        elif stmt.startswith("return "):
            out["return"] = stmt[len("return ") :]
    return out


def polynomial(exprs, names, z_name="z"):
    """The expressions `names` evaluated in turn with z the polynomial variable: exact for
    these (sums and products of literals with powers of z)."""
    scope = {z_name: Polynomial([0.0, 1.0])}
    for name in names:
        scope[name] = eval(exprs[name], {}, scope)  # noqa: S307 (the repository's own header)
    return scope[names[-1]]


def coefficients(p):
    return [float(c) for c in p.coef]


def test_atan_series_is_the_fit(fits):
    exprs = statements(body("atan_series"))
    names = [n for n in exprs if n != "return"] + ["return"]
    expected, err = fits.atan_fit()
    assert coefficients(polynomial(exprs, names)) == expected
    assert err < 1e-17  # (the fit the header documents: its error, times z, below 1e-18)


def test_reduction_constants_are_the_scripts(fits):
    atan2 = " ".join(body("atan2_by_fit").split())

    def table(name):
        values = re.search(rf"{name}\[5\] = \{{([^}}]*)\}}", atan2).group(1)
        return [float(v) for v in values.split(",")]

    assert list(zip(table("kHi"), table("kLo"))) == fits.quarter_pi_multiples()
