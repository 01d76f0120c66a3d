"""Curves and surfaces: NURBS against geomdl, closest points against a dense search refined
by SciPy, the analytic shapes against closed forms, bad inputs."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

import virtmech as vm

geomdl_nurbs = pytest.importorskip("geomdl.NURBS")


def random_knots(rng: np.random.Generator, n: int, p: int) -> np.ndarray:
    """Clamped knots on [0, 1] for n control points of degree p, some interior ones repeated."""
    interior: list[float] = []
    m = n - p - 1
    while len(interior) < m:
        value = float(rng.uniform(0.05, 0.95))
        mult = int(rng.integers(1, min(p, m - len(interior)) + 1)) if rng.random() < 0.3 else 1
        interior += [value] * mult
    return np.concatenate([np.zeros(p + 1), np.sort(interior), np.ones(p + 1)])


def random_curve(rng: np.random.Generator, p: int, n: int | None = None):
    n = n or int(rng.integers(p + 1, p + 7))
    P = rng.uniform(-1, 1, (n, 3))
    w = rng.uniform(0.5, 2.0, n)
    U = random_knots(rng, n, p)
    return P, w, U


def random_surface(rng: np.random.Generator, p: int, q: int):
    nu, nv = int(rng.integers(p + 1, p + 5)), int(rng.integers(q + 1, q + 5))
    grid = np.stack(np.meshgrid(np.linspace(0, 1, nu), np.linspace(0, 1, nv), indexing="ij"), -1)
    P = np.concatenate([grid, rng.uniform(-0.3, 0.3, (nu, nv, 1))], axis=-1)
    P[..., :2] += rng.uniform(-0.05, 0.05, (nu, nv, 2))
    w = rng.uniform(0.5, 2.0, (nu, nv))
    return P, w, random_knots(rng, nu, p), random_knots(rng, nv, q)


def trial_surface(rng: np.random.Generator, trial: int):
    """A random surface for trial `trial` of a search test: bilinear (creased at every
    interior knot) for trials 0 and 1, else of random degrees 1-4; every odd trial with a
    spike (a control point lifted by 1 with a weight of 50)."""
    p, q = (1, 1) if trial < 2 else tuple(int(k) for k in rng.integers(1, 5, 2))
    P, w, Uu, Uv = random_surface(rng, p, q)
    if trial % 2:
        i, j = rng.integers(0, w.shape[0]), rng.integers(0, w.shape[1])
        w[i, j] = 50.0
        P[i, j, 2] += 1.0
    return vm.NurbsSurface(P, w, Uu, Uv, p, q)


def surface_grid(s, n: int = 151) -> np.ndarray:
    """The points of s on an n x n grid of the unit parameter square, (n * n, 3)."""
    g = np.linspace(0, 1, n)
    return np.array([[s.evaluate(u, v) for v in g] for u in g]).reshape(-1, 3)


def geomdl_curve(P, w, U, p):
    c = geomdl_nurbs.Curve()
    c.degree = p
    c.ctrlptsw = [[*(wi * pi), wi] for pi, wi in zip(P, w)]
    c.knotvector = list(U)
    return c


def geomdl_surface(P, w, Uu, Uv, p, q):
    nu, nv = w.shape
    s = geomdl_nurbs.Surface()
    s.degree_u, s.degree_v = p, q
    s.ctrlpts_size_u, s.ctrlpts_size_v = nu, nv
    s.ctrlptsw = [[*(w[i, j] * P[i, j]), w[i, j]] for i in range(nu) for j in range(nv)]
    s.knotvector_u, s.knotvector_v = list(Uu), list(Uv)
    return s


@pytest.mark.parametrize("p", [1, 2, 3, 4, 7])
def test_nurbs_curve_matches_geomdl(p):
    rng = np.random.default_rng(100 + p)
    for _ in range(4):
        P, w, U = random_curve(rng, p)
        c = vm.NurbsCurve(P, w, U, p)
        ref = geomdl_curve(P, w, U, p)
        for u in np.concatenate([[0.0, 1.0], rng.uniform(0, 1, 8)]):
            d = c.derivatives(u, 2)
            assert d.shape == (3, 3)
            expected = np.array(ref.derivatives(float(u), 2))
            np.testing.assert_allclose(d, expected, rtol=1e-10, atol=1e-10)
            np.testing.assert_allclose(c.evaluate(u), expected[0], rtol=1e-10, atol=1e-10)
        # higher orders (up to the degree) follow the same algorithm
        u = float(rng.uniform(0, 1))
        np.testing.assert_allclose(
            c.derivatives(u, p), np.array(ref.derivatives(u, p)), rtol=1e-9, atol=1e-9
        )


@pytest.mark.parametrize("p,q", [(1, 2), (2, 2), (3, 1), (3, 4), (4, 3), (7, 5)])
def test_nurbs_surface_matches_geomdl(p, q):
    rng = np.random.default_rng(10 * p + q)
    for _ in range(2):
        P, w, Uu, Uv = random_surface(rng, p, q)
        s = vm.NurbsSurface(P, w, Uu, Uv, p, q)
        ref = geomdl_surface(P, w, Uu, Uv, p, q)
        params = np.concatenate([[[0, 0], [1, 1], [0, 1]], rng.uniform(0, 1, (6, 2))])
        for u, v in params:
            d = s.derivatives(u, v, 2)
            assert d.shape == (3, 3, 3)
            expected = np.array(ref.derivatives(float(u), float(v), 2))
            np.testing.assert_allclose(d, expected, rtol=1e-10, atol=1e-10)
            np.testing.assert_allclose(s.evaluate(u, v), expected[0, 0], rtol=1e-10, atol=1e-10)


def test_every_degree_and_order_matches_geomdl():
    # the evaluation has an instance per degree up to 3 (5 for curves) and per order up to
    # 2, and one for the rest: every degree (pair) 1-7 and every order 0-7
    rng = np.random.default_rng(5)
    for p in range(1, 8):
        P, w, U = random_curve(rng, p)
        c, ref = vm.NurbsCurve(P, w, U, p), geomdl_curve(P, w, U, p)
        for u in rng.uniform(0, 1, 2):
            for order in range(8):
                expected = np.array(ref.derivatives(float(u), order))
                np.testing.assert_allclose(c.derivatives(u, order), expected, rtol=1e-10,
                                           atol=1e-10, err_msg=f"curve degree {p} order {order}")
    for p in range(1, 8):
        for q in range(1, 8):
            P, w, Uu, Uv = random_surface(rng, p, q)
            s, ref = vm.NurbsSurface(P, w, Uu, Uv, p, q), geomdl_surface(P, w, Uu, Uv, p, q)
            for u, v in rng.uniform(0, 1, (1, 2)):
                for order in range(8):
                    expected = np.array(ref.derivatives(float(u), float(v), order))
                    np.testing.assert_allclose(
                        s.derivatives(u, v, order), expected, rtol=1e-10, atol=1e-10,
                        err_msg=f"surface degrees ({p}, {q}) order {order}")


@pytest.mark.parametrize("p", [3, 7])
def test_nurbs_far_from_zero_and_wide_knots_match_geomdl(p):
    # evaluation runs from each span's Taylor coefficients about its middle: knots 1000 + 250
    # U (far from 0, spans 250 wide) give the shape on U reparametrised, its k-th
    # derivative 250^-k times geomdl's on U (geomdl takes parameters in [0, 1] only)
    rng = np.random.default_rng(7 + p)
    P, w, U = random_curve(rng, p, n=p + 5)
    c, ref = vm.NurbsCurve(P, w, 1000.0 + 250.0 * np.asarray(U), p), geomdl_curve(P, w, U, p)
    k = np.arange(p + 1)[:, None]
    for u in np.concatenate([[0.0, 1.0], rng.uniform(0, 1, 8)]):
        expected = np.array(ref.derivatives(float(u), p))
        scale = np.abs(expected).max(axis=1, keepdims=True)  # each order's own size
        got = c.derivatives(1000.0 + 250.0 * u, p) * 250.0**k
        assert np.all(np.abs(got - expected) <= 1e-9 * np.abs(expected) + 1e-10 * scale), u
    P, w, Uu, Uv = random_surface(rng, p, 2)
    s = vm.NurbsSurface(P, w, 1000.0 + 250.0 * np.asarray(Uu), -500.0 + 250.0 * np.asarray(Uv),
                        p, 2)
    ref = geomdl_surface(P, w, Uu, Uv, p, 2)
    kl = (np.arange(3)[:, None] + np.arange(3)[None, :])[..., None]
    for u, v in rng.uniform(0, 1, (8, 2)):
        expected = np.array(ref.derivatives(float(u), float(v), 2))
        scale = np.abs(expected).max(axis=2, keepdims=True)
        got = s.derivatives(1000.0 + 250.0 * u, -500.0 + 250.0 * v, 2) * 250.0**kl
        assert np.all(np.abs(got - expected) <= 1e-9 * np.abs(expected) + 1e-10 * scale), (u, v)


def test_quarter_circle_and_curvature():
    c = vm.NurbsCurve(
        [[1, 0, 0], [1, 1, 0], [0, 1, 0]], [1, np.sqrt(0.5), 1], [0, 0, 0, 1, 1, 1], 2
    )
    for u in np.linspace(0, 1, 11):
        np.testing.assert_allclose(np.linalg.norm(c.evaluate(u)), 1.0, atol=1e-14)
        assert c.curvature(u) == pytest.approx(1.0, abs=1e-12)
        t = c.tangent(u)
        assert abs(t @ c.evaluate(u)) < 1e-12
    u, point = c.closest_point([2.0, 2.0, 0.3])
    np.testing.assert_allclose(point, [np.sqrt(0.5), np.sqrt(0.5), 0], atol=1e-12)
    assert u == pytest.approx(0.5, abs=1e-12)
    # parameters outside the domain are clamped
    np.testing.assert_allclose(c.evaluate(-1.0), [1, 0, 0])
    np.testing.assert_allclose(c.evaluate(7.0), [0, 1, 0], atol=1e-15)


# --- closest point against a dense search refined by SciPy ----------------------------------


def reference_curve_closest(ref, c, p):
    us = np.linspace(0, 1, 2001)
    d2 = np.array([np.sum((c.evaluate(u) - p) ** 2) for u in us])

    def f(x):
        d = np.array(ref.derivatives(float(x[0]), 1))
        r = d[0] - p
        return 0.5 * r @ r, np.array([d[1] @ r])

    best = None
    for i in np.argsort(d2)[:3]:
        res = minimize(
            f,
            [us[i]],
            jac=True,
            method="L-BFGS-B",
            bounds=[(0, 1)],
            options={"ftol": 0.0, "gtol": 1e-15, "maxiter": 200},
        )
        if best is None or res.fun < best.fun:
            best = res
    return best.x[0], np.array(ref.evaluate_single(float(best.x[0])))


def reference_surface_closest(ref, s, p):
    g = np.linspace(0, 1, 121)
    pts = np.array([[s.evaluate(u, v) for v in g] for u in g])
    d2 = np.sum((pts - p) ** 2, axis=-1)

    def f(x):
        d = np.array(ref.derivatives(float(x[0]), float(x[1]), 1))
        r = d[0, 0] - p
        return 0.5 * r @ r, np.array([d[1, 0] @ r, d[0, 1] @ r])

    best = None
    for k in np.argsort(d2, axis=None)[:3]:
        i, j = np.unravel_index(k, d2.shape)
        res = minimize(
            f,
            [g[i], g[j]],
            jac=True,
            method="L-BFGS-B",
            bounds=[(0, 1), (0, 1)],
            options={"ftol": 0.0, "gtol": 1e-15, "maxiter": 300},
        )
        if best is None or res.fun < best.fun:
            best = res
    uv = best.x
    return uv, np.array(ref.evaluate_single([float(uv[0]), float(uv[1])]))


def test_curve_closest_point_matches_dense_search():
    rng = np.random.default_rng(7)
    on_end = 0
    for p in (1, 2, 3, 4):
        P, w, U = random_curve(rng, p, n=p + 4)
        if p == 3:
            w[2] = 30.0  # a sharp turn: high curvature near control point 2
        c = vm.NurbsCurve(P, w, U, p)
        ref = geomdl_curve(P, w, U, p)
        queries = [rng.uniform(-1.2, 1.2, 3) for _ in range(5)]
        d0, d1 = c.derivatives(0.0, 1), c.derivatives(1.0, 1)
        queries += [
            d0[0] - 0.3 * d0[1] / np.linalg.norm(d0[1]),  # beyond the ends
            d1[0] + 0.3 * d1[1] / np.linalg.norm(d1[1]),
        ]
        if p == 3:
            queries += [P[2] + rng.normal(0, 0.02, 3) for _ in range(3)]
        for q in queries:
            u, point = c.closest_point(q)
            u_ref, point_ref = reference_curve_closest(ref, c, q)
            assert np.linalg.norm(point - q) <= np.linalg.norm(point_ref - q) + 1e-12
            np.testing.assert_allclose(point, point_ref, atol=1e-9)
            on_end += u_ref in (0.0, 1.0)
    assert on_end >= 4


def test_surface_closest_point_matches_dense_search():
    rng = np.random.default_rng(11)
    on_edge = on_corner = 0
    for p, q in ((1, 1), (2, 3), (3, 2)):
        P, w, Uu, Uv = random_surface(rng, p, q)
        if (p, q) == (3, 2):
            P[2, 2, 2] += 0.8
            w[2, 2] = 20.0  # a spike: high curvature
        s = vm.NurbsSurface(P, w, Uu, Uv, p, q)
        ref = geomdl_surface(P, w, Uu, Uv, p, q)
        queries = [np.array([*rng.uniform(-0.2, 1.2, 2), rng.uniform(-0.5, 0.5)]) for _ in range(4)]
        # beyond an edge, beyond a corner
        queries += [
            np.array([-0.3, 0.5, 0.2]),
            np.array([0.4, 1.3, -0.1]),
            np.array([-0.2, -0.3, 0.3]),
            np.array([1.3, 1.2, 0.0]),
        ]
        if (p, q) == (3, 2):
            apex = s.evaluate(*s.closest_point(P[2, 2])[0])
            queries += [apex + rng.normal(0, 0.03, 3) for _ in range(3)]
        for x in queries:
            uv, point = s.closest_point(x)
            uv_ref, point_ref = reference_surface_closest(ref, s, x)
            assert np.linalg.norm(point - x) <= np.linalg.norm(point_ref - x) + 1e-12
            np.testing.assert_allclose(point, point_ref, atol=1e-9)
            at_bound = np.sum((uv_ref == 0.0) | (uv_ref == 1.0))
            on_edge += at_bound >= 1
            on_corner += at_bound == 2
    assert on_edge >= 4 and on_corner >= 2


# --- analytic shapes -------------------------------------------------------------------------


def test_sphere():
    c, r = np.array([0.1, -0.2, 0.3]), 0.5
    s = vm.Sphere(c, r)
    u, v = 0.7, -0.4
    e = np.array([np.cos(u) * np.cos(v), np.sin(u) * np.cos(v), np.sin(v)])
    np.testing.assert_allclose(s.evaluate(u, v), c + r * e, atol=1e-15)
    np.testing.assert_allclose(s.normal(u, v), e, atol=1e-15)
    d = s.derivatives(u, v, 2)
    np.testing.assert_allclose(
        d[1, 0], r * np.array([-np.sin(u) * np.cos(v), np.cos(u) * np.cos(v), 0])
    )
    np.testing.assert_allclose(
        d[0, 1], r * np.array([-np.cos(u) * np.sin(v), -np.sin(u) * np.sin(v), np.cos(v)])
    )
    np.testing.assert_allclose(
        d[1, 1], r * np.array([np.sin(u) * np.sin(v), -np.cos(u) * np.sin(v), 0]), atol=1e-15
    )
    np.testing.assert_allclose(
        d[2, 0], r * np.array([-np.cos(u) * np.cos(v), -np.sin(u) * np.cos(v), 0])
    )
    k = s.curvature(u, v)
    assert k["mean"] == pytest.approx(-1 / r) and k["gaussian"] == pytest.approx(1 / r**2)
    uv, point = s.closest_point(c + 2.0 * e)
    np.testing.assert_allclose(uv, [u, v], atol=1e-14)
    np.testing.assert_allclose(point, c + r * e, atol=1e-15)


def test_cylinder():
    a, dvec, r = np.array([0.0, 0.1, 0.0]), np.array([0.0, 0.0, 2.0]), 0.2
    cyl = vm.Cylinder(a, dvec, r)
    np.testing.assert_allclose(cyl.direction, [0, 0, 1])
    e1, e2 = cyl.e1, cyl.e2
    np.testing.assert_allclose(np.cross(cyl.direction, e1), e2, atol=1e-15)
    u, v = 1.1, -0.3
    radial = np.cos(u) * e1 + np.sin(u) * e2
    np.testing.assert_allclose(cyl.evaluate(u, v), a + r * radial + v * cyl.direction, atol=1e-15)
    np.testing.assert_allclose(cyl.normal(u, v), radial, atol=1e-15)
    d = cyl.derivatives(u, v, 2)
    np.testing.assert_allclose(d[0, 1], cyl.direction)
    np.testing.assert_allclose(d[2, 0], -r * radial, atol=1e-15)
    k = cyl.curvature(u, v)
    assert k["mean"] == pytest.approx(-0.5 / r) and k["gaussian"] == pytest.approx(0, abs=1e-12)
    uv, point = cyl.closest_point(a + 0.7 * radial + v * cyl.direction)
    np.testing.assert_allclose(uv, [u, v], atol=1e-14)
    np.testing.assert_allclose(point, a + r * radial + v * cyl.direction, atol=1e-15)


def test_plane():
    o, n = np.array([0.0, 0.0, 0.1]), np.array([0.0, 1.0, 1.0])
    pl = vm.Plane(o, n)
    nn = n / np.linalg.norm(n)
    np.testing.assert_allclose(pl.normal(0.3, 0.4), nn)
    np.testing.assert_allclose(pl.evaluate(0.3, 0.4), o + 0.3 * pl.e1 + 0.4 * pl.e2)
    x = np.array([0.2, -0.5, 0.9])
    uv, point = pl.closest_point(x)
    np.testing.assert_allclose(point, x - ((x - o) @ nn) * nn, atol=1e-15)
    np.testing.assert_allclose(pl.evaluate(*uv), point, atol=1e-15)
    d = pl.derivatives(0.3, 0.4, 1)
    assert d.shape == (2, 2, 3)
    np.testing.assert_allclose(d[1, 1], 0)


# --- bad inputs ---------------------------------------------------------------------------


CURVE = ([[0, 0, 0], [1, 0, 0], [1, 1, 0]], [1, 1, 1], [0, 0, 0, 1, 1, 1], 2)


@pytest.mark.parametrize(
    "index,value,name",
    [
        (0, [[0, 0], [1, 0], [1, 1]], "control_points"),
        (1, [1, -1, 1], "weights"),
        (1, [1, 1], "weights"),
        (2, [0, 0, 1, 1, 1], "knots"),
        (2, [0, 0, 0, 1, 0.5, 1], "knots"),
        (3, 0, "degree"),
        (3, 3, "control_points"),
    ],
)
def test_curve_bad_inputs(index, value, name):
    args = list(CURVE)
    args[index] = value
    with pytest.raises(ValueError, match=name):
        vm.NurbsCurve(*args)


def test_surface_and_shape_bad_inputs():
    P = np.zeros((3, 3, 3))
    w = np.ones((3, 3))
    U = [0, 0, 0, 1, 1, 1]
    vm.NurbsSurface(P, w, U, U, 2, 2)
    with pytest.raises(ValueError, match="control_points"):
        vm.NurbsSurface(np.zeros((3, 3, 2)), w, U, U, 2, 2)
    with pytest.raises(ValueError, match="weights"):
        vm.NurbsSurface(P, np.ones((3, 2)), U, U, 2, 2)
    with pytest.raises(ValueError, match="knots_v"):
        vm.NurbsSurface(P, w, U, [0, 0, 1, 1], 2, 2)
    with pytest.raises(ValueError, match="degree_u"):
        vm.NurbsSurface(P, w, U, U, 9, 2)
    with pytest.raises(ValueError, match="radius"):
        vm.Sphere([0, 0, 0], -1.0)
    with pytest.raises(ValueError, match="direction"):
        vm.Cylinder([0, 0, 0], [0, 0, 0], 1.0)
    with pytest.raises(ValueError, match="normal"):
        vm.Plane([0, 0, 0], [0, 0])
    with pytest.raises(ValueError, match="order"):
        vm.Sphere([0, 0, 0], 1.0).derivatives(0, 0, -1)


def test_closest_point_never_worse_than_a_dense_grid():
    """Creases (degree 1, knots of full multiplicity), dips and spikes (a weight of 50)."""
    rng = np.random.default_rng(1)
    for trial in range(6):
        s = trial_surface(rng, trial)
        pts = surface_grid(s)
        for _ in range(10):
            x = np.array([*rng.uniform(-0.5, 1.5, 2), rng.uniform(-1, 1.5)])
            _, point = s.closest_point(x)
            assert np.linalg.norm(point - x) <= np.min(np.linalg.norm(pts - x, axis=1)) + 1e-12
    gc = np.linspace(0, 1, 5001)
    for trial in range(8):
        p = 1 if trial < 2 else int(rng.integers(1, 5))
        P, w, U = random_curve(rng, p, n=p + 6)
        if trial % 2:
            w[rng.integers(0, len(w))] = 50.0
        c = vm.NurbsCurve(P, w, U, p)
        pts = np.array([c.evaluate(u) for u in gc])
        for _ in range(10):
            x = rng.uniform(-1.2, 1.2, 3)
            _, point = c.closest_point(x)
            assert np.linalg.norm(point - x) <= np.min(np.linalg.norm(pts - x, axis=1)) + 1e-12


def test_closest_points_in_one_call_are_closest_point_row_by_row():
    rng = np.random.default_rng(11)
    X = rng.normal(size=(40, 3))
    curve = vm.NurbsCurve(*random_curve(rng, 3), 3)
    u, P = curve.closest_points(X)
    assert u.shape == (40,) and P.shape == (40, 3)
    for i, x in enumerate(X):
        ui, pi = curve.closest_point(x)
        assert u[i] == ui
        np.testing.assert_array_equal(P[i], pi)
    surfaces = [vm.NurbsSurface(*random_surface(rng, 3, 2), 3, 2), vm.Sphere([0.1, 0, 0], 0.5),
                vm.Cylinder([0, 0, 0], [0, 0, 1], 0.3), vm.Plane([0, 0, 0.2], [0, 1, 1])]
    for s in surfaces:
        uv, P, N = s.closest_points(X)
        assert uv.shape == (40, 2) and P.shape == N.shape == (40, 3)
        for i, x in enumerate(X):
            uvi, pi = s.closest_point(x)
            np.testing.assert_array_equal(uv[i], uvi)
            np.testing.assert_array_equal(P[i], pi)
            np.testing.assert_array_equal(N[i], s.normal(*uvi))
    with pytest.raises(ValueError, match=r"X: expected an array of shape \(n, 3\), got shape "
                                         r"\(4, 2\)"):
        curve.closest_points(np.zeros((4, 2)))
    with pytest.raises(ValueError, match=r"X: expected an array of shape \(n, 3\)"):
        surfaces[1].closest_points(np.zeros(3))


def test_surface_closest_points_never_worse_than_a_dense_grid_over_many_points():
    # the search looks only in the sample cells whose bounding sphere is nearer than the
    # nearest sample, and skips a start whose cells are all farther than the best found:
    # over points near the surface (where most cells are ruled out) and far from it, on
    # spiky surfaces (a weight of 50) and creased ones (degree 1, a knot of multiplicity
    # >= the degree: there a cell's corners take the derivatives from inside it, and a
    # start is inside), never a worse answer for it
    rng = np.random.default_rng(8)
    for trial in range(14):
        s = trial_surface(rng, trial)
        dense = surface_grid(s)
        on = [(rng.uniform(0, 1), rng.uniform(0, 1)) for _ in range(40)]
        near = np.array([s.evaluate(u, v) + rng.uniform(-0.05, 0.05) * s.normal(u, v)
                         for u, v in on])
        X = np.concatenate([near, rng.uniform(-0.5, 1.5, (20, 3))])
        _, points, _ = s.closest_points(X)
        d = np.linalg.norm(points - X, axis=1)
        ref = np.min(np.linalg.norm(dense[None] - X[:, None], axis=2), axis=1)
        assert np.all(d <= ref + 1e-12), trial


def test_surface_closest_point_does_not_depend_on_the_knots():
    # knot insertion (geomdl) changes the parametrisation, the samples and the cells' bounds,
    # not the shape: 2 x 2 spans (17 x 17 samples, their distances kept on the stack: at
    # most 1024 are) and the same surface in 8 x 8 spans (65 x 65 samples, more than are
    # kept: recomputed) give the same nearest distances
    from geomdl import operations

    rng = np.random.default_rng(21)
    P = np.concatenate([np.stack(np.meshgrid(*[np.linspace(0, 1, 5)] * 2, indexing="ij"), -1),
                        rng.uniform(-0.3, 0.3, (5, 5, 1))], axis=-1)
    w = rng.uniform(0.5, 2.0, (5, 5))
    U = np.array([0, 0, 0, 0, 0.5, 1, 1, 1, 1.0])
    coarse = vm.NurbsSurface(P, w, U, U, 3, 3)
    ref = geomdl_surface(P, w, U, U, 3, 3)
    for k in [0.125, 0.25, 0.375, 0.625, 0.75, 0.875]:
        operations.insert_knot(ref, [k, k], [1, 1])
    nu, nv = ref.ctrlpts_size_u, ref.ctrlpts_size_v
    assert (nu, nv) == (11, 11)
    Pw = np.array(ref.ctrlptsw).reshape(nu, nv, 4)
    fine = vm.NurbsSurface(Pw[..., :3] / Pw[..., 3:], Pw[..., 3], ref.knotvector_u,
                           ref.knotvector_v, 3, 3)
    u, v = rng.uniform(0, 1, (2, 40))
    np.testing.assert_allclose([fine.evaluate(a, b) for a, b in zip(u, v)],
                               [coarse.evaluate(a, b) for a, b in zip(u, v)], atol=1e-12)
    X = rng.uniform([-0.2, -0.2, -0.5], [1.2, 1.2, 0.5], (200, 3))
    _, near_coarse, _ = coarse.closest_points(X)
    _, near_fine, _ = fine.closest_points(X)
    d_coarse = np.linalg.norm(near_coarse - X, axis=1)
    d_fine = np.linalg.norm(near_fine - X, axis=1)
    np.testing.assert_allclose(d_fine, d_coarse, rtol=0, atol=1e-9)
    # and neither is worse than a dense grid of the shape (geomdl's points: the reference
    # evaluates independently of the search's samples)
    ref.sample_size = 101
    pts = np.array(ref.evalpts)
    d_grid = np.linalg.norm(pts[None, :, :] - X[:, None, :], axis=2).min(axis=1)
    assert np.all(d_coarse <= d_grid + 1e-12) and np.all(d_fine <= d_grid + 1e-12)


def test_surface_closest_point_beside_a_crease_takes_the_nearer_face():
    # a V-shaped valley of two planes meeting at u = 0.5 (degree 1, an interior knot), a
    # point just left of its bottom: the nearest sample is on the crease, and a start there
    # (derivatives from the right) descends to the right face; the left face is nearer
    P = np.array([[[0, 0, 0.3], [0, 1, 0.3]], [[0.5, 0, 0], [0.5, 1, 0]],
                  [[1, 0, 0.3], [1, 1, 0.3]]])
    s = vm.NurbsSurface(P, np.ones((3, 2)), [0, 0, 0.5, 1, 1], [0, 0, 1, 1], 1, 1)
    x = np.array([0.49, 0.4, 0.05])
    uv, point = s.closest_point(x)
    # the left face z = 0.6 (0.5 - x): the distance and foot from the plane's normal
    n = np.array([0.6, 0.0, 1.0]) / np.sqrt(1.36)
    height = (x[2] - 0.6 * (0.5 - x[0])) / np.sqrt(1.36)
    np.testing.assert_allclose(np.linalg.norm(point - x), height, rtol=1e-12)
    np.testing.assert_allclose(point, x - height * n, atol=1e-12)
    np.testing.assert_allclose(uv, [point[0], 0.4], atol=1e-12)


def test_surface_closest_point_just_beside_a_crease_from_its_corner():
    # a bilinear patch (every interior knot a crease) with a spike of weight 50 whose nearest
    # point lies 0.4e-3 beside the crease v = 0.25949: the start inside the cell alone ends
    # 3.2 cm away; the corner on the crease reaches it (both are run on a creased surface)
    P = np.array([
        [[0.0387, 0.0178, -0.1418], [0.0264, 0.2309, 0.2110], [-0.0488, 0.4321, -0.2668],
         [-0.0199, 0.5564, -0.1201], [-0.0097, 0.8173, 0.1587], [-0.0466, 1.0130, -0.1677]],
        [[0.9657, 0.0406, 0.0186], [0.9938, 0.1868, -0.0890], [0.9651, 0.4080, -0.0191],
         [1.0154, 0.6017, 1.1632], [1.0355, 0.7696, 0.0008], [1.0306, 0.9721, 0.1672]]])
    w = np.array([[1.6244, 1.3875, 1.4468, 0.7345, 1.6898, 1.0797],
                  [0.7795, 1.2223, 1.7144, 50.0, 1.8531, 0.5953]])
    s = vm.NurbsSurface(P, w, [0, 0, 1, 1], [0, 0, 0.0731, 0.2595, 0.4363, 0.8171, 1, 1], 1, 1)
    x = np.array([0.5493, 0.4165, -0.0772])
    _, point = s.closest_point(x)
    assert np.linalg.norm(point - x) <= np.min(np.linalg.norm(surface_grid(s, 301) - x, axis=1))


def test_closest_point_from_a_start_is_the_local_one():
    # a sphere seen as a surface (u wraps: unbounded), from starts near the answer: the
    # radial point (closed form); a NURBS patch: the global answer from near it, and held
    # to a box that excludes it, no point of the box nearer
    c, r = np.array([0.1, -0.2, 0.3]), 0.5
    s = vm.Sphere(c, r)
    rng = np.random.default_rng(4)
    for _ in range(20):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        x = c + (r + rng.uniform(0.01, 0.3)) * d
        u0, v0 = s.closest_point(c + r * d)[0] + rng.normal(0, 0.2, 2)
        uv, point = s.closest_point_from(x, [u0, np.clip(v0, -1.5, 1.5)],
                                         lo=[-np.inf, -np.pi / 2], hi=[np.inf, np.pi / 2])
        np.testing.assert_allclose(point, c + r * d, atol=1e-10)
        np.testing.assert_allclose(s.evaluate(*uv), point, atol=1e-12)
    # NURBS, a start near the global answer gives it
    P, w, Uu, Uv = random_surface(rng, 3, 3)
    n = vm.NurbsSurface(P, w, Uu, Uv, 3, 3)
    x = n.evaluate(0.4, 0.6) + 0.02 * n.normal(0.4, 0.6)
    uv_g, p_g = n.closest_point(x)
    uv, p = n.closest_point_from(x, uv_g + 0.05)
    np.testing.assert_allclose(p, p_g, atol=1e-12)
    # held to a box: the answer on its edge, no nearer point of the surface inside the box
    uv, p = n.closest_point_from(x, [0.1, 0.1], lo=[0.0, 0.0], hi=[0.3, 0.3])
    assert np.all(uv >= 0.0) and np.all(uv <= 0.3) and max(uv) == 0.3
    g = np.linspace(0, 0.3, 61)
    box = np.array([[n.evaluate(a, b) for b in g] for a in g]).reshape(-1, 3)
    assert np.linalg.norm(p - x) <= np.min(np.linalg.norm(box - x, axis=1)) + 1e-12
    with pytest.raises(ValueError, match=r"start: expected an array of shape \(2,\)"):
        n.closest_point_from(x, [0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="start: expected finite numbers"):
        n.closest_point_from(x, [np.nan, 0.2])
    with pytest.raises(ValueError, match="hi: expected >= lo"):
        n.closest_point_from(x, [0.1, 0.2], lo=[0.5, 0.0], hi=[0.4, 1.0])


def test_curve_closest_points_never_worse_than_a_dense_grid_over_many_points():
    # the search skips sample intervals whose bounding sphere is farther than the best found:
    # over many points and spiky curves (a weight of 50), never a worse answer for it
    rng = np.random.default_rng(5)
    gc = np.linspace(0, 1, 4001)
    for trial in range(20):
        p = 1 if trial < 4 else int(rng.integers(1, 6))
        P, w, U = random_curve(rng, p, n=p + int(rng.integers(2, 12)))
        if trial % 2:
            w[rng.integers(0, len(w))] = 50.0
        c = vm.NurbsCurve(P, w, U, p)
        dense = np.array([c.evaluate(u) for u in gc])
        X = rng.uniform(-1.2, 1.2, (100, 3))
        _, points = c.closest_points(X)
        d = np.linalg.norm(points - X, axis=1)
        ref = np.min(np.linalg.norm(dense[None] - X[:, None], axis=2), axis=1)
        assert np.all(d <= ref + 1e-12), trial
