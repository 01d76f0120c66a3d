"""The polynomial coefficients of src/trig.hpp, from mpmath (50 digits).

Chebyshev fits (mpmath.chebyfit) of
  (atan(u) - u) / u^3         in z = u^2 on [0, 1/4]   (|u| <= 1/2),              13 terms
  (sin r - r) / r^3           in z = r^2 on [0, (pi/4)^2],                             6 terms
  (cos r - 1 + r^2/2) / r^4   in z = r^2 on [0, (pi/4)^2],                             6 terms
and the constants of the reductions. Run: python scripts/trig_fits.py (mpmath comes with
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


def sin_fit():
    """S of sin r = r + r^3 S(r^2), |r| <= pi/4: 6 coefficients, and the error."""
    return _fit(_ratio(lambda z: (mp.sin(mp.sqrt(z)) - mp.sqrt(z)) / (mp.sqrt(z) * z),
                       mp.mpf(-1) / 6), 0, (mp.pi / 4) ** 2, 6)


def cos_fit():
    """C of cos r = 1 - r^2/2 + r^4 C(r^2), |r| <= pi/4: 6 coefficients, and the error."""
    return _fit(_ratio(lambda z: (mp.cos(mp.sqrt(z)) - 1 + z / 2) / (z * z), mp.mpf(1) / 24),
                0, (mp.pi / 4) ** 2, 6)


def split(x, parts, bits=33):
    """x as a sum of doubles, all but the last of `bits` significant bits."""
    out = []
    for _ in range(parts - 1):
        m, e = mp.frexp(x)
        head = mp.ldexp(mp.floor(m * 2**bits), e - bits)
        out.append(float(head))
        x -= head
    out.append(float(x))
    return out


def half_pi_parts():
    """pi/2 in three parts for the sine's reduction (Cody and Waite)."""
    return split(mp.pi / 2, 3)


def quarter_pi_multiples():
    """k pi/4, k = 0..4, each as a double and its remainder (atan2's reduction)."""
    out = []
    for k in range(5):
        v = k * mp.pi / 4
        out.append((float(v), float(v - mp.mpf(float(v)))))
    return out


def two_over_pi():
    return float(2 / mp.pi)


def main():
    for name, fit in (("atan P", atan_fit), ("sin S", sin_fit), ("cos C", cos_fit)):
        coeffs, err = fit()
        print(f"{name}: max error {mp.nstr(err, 3)}")
        for c in coeffs:
            print(f"  {c!r}")
    print("pi/2 in three parts:", half_pi_parts())
    print("k pi/4, k = 0..4, as a double and its remainder:")
    for hi, lo in quarter_pi_multiples():
        print(f"  {hi!r} {lo!r}")
    print("2/pi:", two_over_pi())


if __name__ == "__main__":
    main()
