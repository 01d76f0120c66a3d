"""The polynomial coefficients of src/trig.hpp, from mpmath (50 digits).

The Chebyshev fit (mpmath.chebyfit) of
  (atan(u) - u) / u^3   in z = u^2 on [0, 1/4]   (|u| <= 1/2), 13 terms
and the constants of atan2's reduction. Run: python scripts/trig_fits.py (mpmath comes with
the test extra: scripts/setup.sh, or pip install .[test]). tests/python/test_trig_fits.py
regenerates them and compares them with the header.
"""

import mpmath as mp

mp.mp.dps = 50


def _ratio(f, z0):
    def g(z):
        return z0 if z == 0 else f(z)

    return g


def _fit(f, lo, hi, n):
    """The fit's coefficients as doubles, lowest degree first, and its largest error."""
    try:  # mpmath 1.4 orders the coefficients as asked; 1.3 highest degree first
        poly, err = mp.chebyfit(f, [lo, hi], n, error=True, asc=True)
    except TypeError:
        poly, err = mp.chebyfit(f, [lo, hi], n, error=True)
        poly = poly[::-1]
    return [float(c) for c in poly], err


def atan_fit():
    """P of atan(u) = u + u z P(z), z = u^2 <= 1/4: 13 coefficients, and the error."""
    return _fit(_ratio(lambda z: (mp.atan(mp.sqrt(z)) - mp.sqrt(z)) / (mp.sqrt(z) * z),
                       mp.mpf(-1) / 3), 0, mp.mpf(1) / 4, 13)


def quarter_pi_multiples():
    """k pi/4, k = 0..4, each as a double and its remainder (atan2's reduction)."""
    out = []
    for k in range(5):
        v = k * mp.pi / 4
        out.append((float(v), float(v - mp.mpf(float(v)))))
    return out


def main():
    coeffs, err = atan_fit()
    print(f"atan P: max error {mp.nstr(err, 3)}")
    for c in coeffs:
        print(f"  {c!r}")
    print("k pi/4, k = 0..4, as a double and its remainder:")
    for hi, lo in quarter_pi_multiples():
        print(f"  {hi!r} {lo!r}")


if __name__ == "__main__":
    main()
