"""The polynomial coefficients of src/trig.hpp, from mpmath (50 digits).

Chebyshev fits (mpmath.chebyfit) of
  (atan(u) - u) / u^3         in z = u^2 on [0, 1/4]   (|u| <= 1/2),              13 terms
  (sin r - r) / r^3           in z = r^2 on [0, (pi/4)^2],                             6 terms
  (cos r - 1 + r^2/2) / r^4   in z = r^2 on [0, (pi/4)^2],                             6 terms
and the constants of the reductions. Run: python scripts/trig_fits.py (mpmath comes with
the test extra: scripts/setup.sh, or pip install .[test]).
"""

import mpmath as mp

mp.mp.dps = 50


def _ratio(f, z0):
    def g(z):
        return z0 if z == 0 else f(z)

    return g


def fit(name, f, lo, hi, n):
    poly, err = mp.chebyfit(f, [lo, hi], n, error=True)
    coeffs = [float(c) for c in reversed(poly)]  # lowest degree first
    print(f"{name}: max error {mp.nstr(err, 3)}")
    for c in coeffs:
        print(f"  {c!r}")


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


def main():
    fit("atan P", _ratio(lambda z: (mp.atan(mp.sqrt(z)) - mp.sqrt(z)) / (mp.sqrt(z) * z),
                         mp.mpf(-1) / 3), 0, mp.mpf(1) / 4, 13)
    fit("sin S", _ratio(lambda z: (mp.sin(mp.sqrt(z)) - mp.sqrt(z)) / (mp.sqrt(z) * z),
                        mp.mpf(-1) / 6), 0, (mp.pi / 4) ** 2, 6)
    fit("cos C", _ratio(lambda z: (mp.cos(mp.sqrt(z)) - 1 + z / 2) / (z * z), mp.mpf(1) / 24),
        0, (mp.pi / 4) ** 2, 6)
    print("pi/2 in three parts:", split(mp.pi / 2, 3))
    print("k pi/4, k = 0..4, as a double and its remainder:")
    for k in range(5):
        v = k * mp.pi / 4
        print(f"  {float(v)!r} {float(v - mp.mpf(float(v)))!r}")
    print("2/pi:", float(2 / mp.pi))


if __name__ == "__main__":
    main()
