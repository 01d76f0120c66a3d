"""Properties of the range and null filters (eqs. 5, 9), rank-deficient and near-singular
cases included. Norms are spectral (2-norms) throughout."""

from __future__ import annotations

import mpmath as mp
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import virtmech as vm

# the filters never form J^T W J: their errors are rounding times the conditioning of the
# orthogonal factorisation of sqrt(W) J, not its square
TOL = 1e-12
REF_TOL = 1e-8  # against the 40-digit reference
RANK_TOL = 1e-10  # kPinvTolerance: singular values of sqrt(W) J below this (relative) are 0

# magnitudes a Jacobian has in SI units (zero, or 1e-3 .. 10)
finite = st.one_of(st.just(0.0), st.floats(1e-3, 10), st.floats(-10, -1e-3))


@st.composite
def jacobians(draw):
    """A (6, n) Jacobian, n = 1 .. 8, sometimes rank-deficient: a repeated, scaled-copy or
    zero column, or planar rows zeroed."""
    n = draw(st.integers(1, 8))
    J = draw(arrays(np.float64, (6, n), elements=finite))
    kind = draw(st.sampled_from(["generic", "repeat", "scaled", "zero", "planar"]))
    if kind == "repeat" and n > 1:
        J[:, -1] = J[:, 0]
    elif kind == "scaled" and n > 1:
        J[:, -1] = J[:, 0] * draw(st.floats(-2, 2))
    elif kind == "zero":
        J[:, draw(st.integers(0, n - 1))] = 0.0
    elif kind == "planar":
        J[[2, 3, 4], :] = 0.0  # planar motion: no z, no rx, ry
    return J


weights = arrays(np.float64, 6, elements=st.one_of(st.just(0.0), st.floats(0.01, 10)))

# the Probe (Fig. 3) near its singular pose: stylus perpendicular to the plane (a = b = 0),
# where sqrt(W) J with translational weights loses rank
L = 0.1
PROBES = [
    vm.Probe(np.zeros(3), np.array([0.0, 0.0, 1.0]), length=L),
    vm.Probe(np.array([0.2, -0.1, 0.05]), np.array([1.0, 2.0, 2.0]) / 3.0, length=L),
]
PROBE_WEIGHTS = {
    "translational": np.array([1, 1, 1, 0, 0, 0], float),
    "rotational": np.array([0, 0, 0, L * L, L * L, L * L], float),
    "full": np.array([1, 1, 1, L * L, L * L, L * L], float),
}


@st.composite
def probe_cases(draw):
    """(J, W) of a Probe with the stylus tilted ~tilt (1e-5 .. 1 rad) from the plane normal."""
    probe = PROBES[draw(st.integers(0, len(PROBES) - 1))]
    tilt = 10.0 ** draw(st.floats(-5, 0))
    phi = draw(st.floats(0, 2 * np.pi))
    x, y = draw(st.floats(-0.1, 0.1)), draw(st.floats(-0.1, 0.1))
    c = draw(st.floats(-np.pi, np.pi))
    J = probe.jacobian(np.array([x, y, tilt * np.cos(phi), tilt * np.sin(phi), c]))
    return J, PROBE_WEIGHTS[draw(st.sampled_from(sorted(PROBE_WEIGHTS)))]


def norm(M):
    return float(np.linalg.norm(M, 2)) if M.size else 0.0


def sqrt_weighted(J, W):
    return np.sqrt(W)[:, None] * J


def numerical_rank(M):
    """Rank with singular values below RANK_TOL of the largest counted as 0; None when one lies
    within a factor 1e3 of that cut (pivots and singular values may decide differently)."""
    s = np.linalg.svd(M, compute_uv=False)
    if s.size == 0 or not s[0] > 0:
        return 0
    rel = s / s[0]
    if np.any((rel > RANK_TOL * 1e-3) & (rel < RANK_TOL * 1e3)):
        return None
    return int(np.sum(rel > RANK_TOL))


def sqrtm(W):
    """Symmetric square root; eigenvalues at rounding level (64 eps of the largest) are 0."""
    lam, V = np.linalg.eigh(W)
    lam[lam <= 64 * np.finfo(float).eps * lam.max()] = 0.0
    return (V * np.sqrt(lam)) @ V.T


def reference_range_filter(J, W):
    """W J (J^T W J)^+ J^T in 40 digits; (J^T W J)^+ by SVD, singular values below RANK_TOL^2
    of the largest (RANK_TOL on sqrt(W) J) counted as 0."""
    with mp.workdps(40):
        Jm = mp.matrix(J.tolist())
        Wm = mp.diag([mp.mpf(w) for w in W]) if W.ndim == 1 else mp.matrix(W.tolist())
        WJ = Wm * Jm
        H = Jm.T * WJ
        U, S, V = mp.svd_r(H)
        cut = mp.mpf(RANK_TOL) ** 2 * max(S)
        Hp = mp.zeros(H.rows, H.rows)
        for k in range(len(S)):
            if S[k] > cut and S[k] > 0:
                Hp += V[k, :].T * U[:, k].T / S[k]
        return np.array((WJ * Hp * Jm.T).tolist(), dtype=float)


def soft_null_reference(J, W):
    """N = I - S (A_phi^+)^T J^T, A = S J, S = sqrt(W), A_phi^+ = V diag(phi_i / sigma_i) U^T
    with the soft rank's factors phi_i = smoothstep((sigma_i / |A|_F - 1e-5) / (1e-3 -
    1e-5)) (docs/theory.md, 5), by NumPy's SVD; and the least sigma_i / |A|_F of the singular
    values above the rank cut (1 where there are none)."""
    S = np.diag(np.sqrt(W)) if W.ndim == 1 else sqrtm(W)
    A = S @ J
    frob = np.linalg.norm(A)
    if A.size == 0 or not frob > 0:
        return np.eye(6), 1.0
    U, sigma, Vt = np.linalg.svd(A, full_matrices=False)
    t = np.clip((sigma / frob - 1e-5) / (1e-3 - 1e-5), 0.0, 1.0)
    phi = t * t * (3.0 - 2.0 * t)
    f = np.divide(phi, sigma, out=np.zeros_like(sigma), where=phi > 0)
    kept = sigma > RANK_TOL * sigma[0]
    smallest = float((sigma[kept] / frob).min()) if kept.any() else 1.0
    return np.eye(6) - S @ U @ np.diag(f) @ Vt @ J.T, smallest


def check_filter_properties(J, W):
    P = vm.range_filter(J, W)
    N = vm.null_filter(J, W)
    assert np.all(np.isfinite(P))
    N_soft, smallest = soft_null_reference(J, W)
    soft = smallest < 1e-2
    if soft:
        # near a singular pose the null filter counts the small singular values in part
        # (continuous where the rank would flip); P keeps the factorisation's rank
        assert norm(N - N_soft) <= 1e-6 * max(1.0, norm(N_soft))
        N = np.eye(6) - P  # (the properties below are P's)
    else:
        np.testing.assert_array_equal(N, np.eye(6) - P)  # the same factorisation
    # a projector, oblique when W has zeros (its norm grows near a singular pose)
    assert norm(P @ P - P) <= TOL * max(1.0, norm(P)) ** 2
    np.testing.assert_allclose(P @ P, P, atol=1e-6 * max(1.0, np.abs(P).max()))  # max-abs
    # null-space forces do no work along the weighted motion
    WJ = W @ J if W.ndim == 2 else W[:, None] * J
    assert norm(N @ WJ) <= TOL * norm(WJ)
    # zero-weighted axes get no range force, exactly
    zero = np.all(W == 0.0, axis=1) if W.ndim == 2 else W == 0.0
    assert np.all(P[zero, :] == 0.0)
    # ... nor along any motion of J when the weights keep all of its rank; the product
    # J^T N itself rounds to eps |J| |N| (|N| = 1 unless N is oblique)
    r_w = numerical_rank(sqrt_weighted(J, W) if W.ndim == 1 else sqrtm(W) @ J)
    if r_w is not None and r_w == numerical_rank(J):
        assert norm(J.T @ N) <= TOL * norm(J) * max(1.0, norm(N))
    return P, r_w


def check_against_reference(J, W):
    """The properties, then P against the 40-digit reference; False if the rank is ambiguous
    at RANK_TOL (then there is no one reference)."""
    P, r_w = check_filter_properties(J, W)
    if r_w is None:
        return False
    R = reference_range_filter(J, W)
    assert norm(P - R) <= REF_TOL * max(1.0, norm(R))
    return True


@settings(max_examples=500, deadline=None, derandomize=True)
@given(jacobians(), weights)
def test_filter_properties_random(J, W):
    """Idempotence, no work along weighted or free motion, zero rows for zero weights."""
    check_filter_properties(J, W)


@settings(max_examples=80, deadline=None, derandomize=True)
@given(jacobians(), weights)
def test_range_filter_matches_high_precision_reference(J, W):
    check_against_reference(J, W)


@settings(max_examples=200, deadline=None, derandomize=True)
@given(probe_cases())
def test_filter_properties_probe_near_singular(case):
    check_filter_properties(*case)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(probe_cases())
def test_probe_matches_high_precision_reference(case):
    check_against_reference(*case)


def test_probe_tilt_sweep_is_exact():
    # the case that forming J^T W J got wrong: translational weights, tilt 1e-5 .. 1 rad
    W = PROBE_WEIGHTS["translational"]
    for probe in PROBES:
        for tilt in np.logspace(-5, 0, 11):
            J = probe.jacobian(np.array([0.01, -0.02, tilt, 0.0, 0.3]))
            assert numerical_rank(sqrt_weighted(J, W)) == 3
            assert check_against_reference(J, W)
            # full rank down to 1e-5 rad: P grows like 1 / tilt
            assert norm(vm.range_filter(J, W)) > 0.1 / tilt


@settings(max_examples=300, deadline=None, derandomize=True)
@given(jacobians())
def test_unweighted_filters_are_complementary_orthogonal_projectors(J):
    P = vm.range_filter(J, np.ones(6))
    N = vm.null_filter(J, np.ones(6))
    N_soft, smallest = soft_null_reference(J, np.ones(6))
    if smallest < 1e-2:  # the null filter's soft rank (see check_filter_properties)
        assert norm(N - N_soft) <= 1e-6 * max(1.0, norm(N_soft))
        return
    np.testing.assert_allclose(P + N, np.eye(6), atol=1e-12)
    np.testing.assert_allclose(P, P.T, atol=1e-12)
    np.testing.assert_allclose(P @ N, 0.0, atol=1e-12)
    # P projects onto the column space of J (the subspace itself is known to eps / s_min)
    r = numerical_rank(J)
    if r is not None:
        U = np.linalg.svd(J, full_matrices=False)[0]
        np.testing.assert_allclose(P, U[:, :r] @ U[:, :r].T, atol=1e-6)


def test_full_weight_matrix_equals_diagonal_vector():
    rng = np.random.default_rng(3)
    J = rng.normal(size=(6, 3))
    W = np.array([1.0, 2.0, 0.0, 0.5, 0.5, 0.1])
    np.testing.assert_allclose(vm.range_filter(J, np.diag(W)), vm.range_filter(J, W), atol=1e-12)


def test_full_weight_matrix_matches_reference():
    # W = B B^T with small integer B: exact in floating point, so its rank is exact too
    rng = np.random.default_rng(5)
    for trial in range(40):
        J = rng.normal(size=(6, 1 + trial % 8))
        if trial % 4 == 1:
            J[:, -1] = J[:, 0]
        B = rng.integers(-3, 4, size=(6, 6 - trial % 4)).astype(float)
        assert check_against_reference(J, B @ B.T)
        # zero rows and columns of W (those axes unweighted): exactly zero rows of P
        B[[1, 4], :] = 0.0
        assert check_against_reference(J, B @ B.T)


def test_pose_error_definition():
    rng = np.random.default_rng(4)
    for _ in range(20):
        Ra = vm.so3_exp(rng.normal(size=3))
        Rb = vm.so3_exp(rng.normal(size=3))
        Ta, Tb = np.eye(4), np.eye(4)
        Ta[:3, :3], Tb[:3, :3] = Ra, Rb
        Ta[:3, 3], Tb[:3, 3] = rng.normal(size=3), rng.normal(size=3)
        e = vm.pose_error(Ta, Tb)
        np.testing.assert_allclose(e[:3], Ta[:3, 3] - Tb[:3, 3], atol=1e-15)
        np.testing.assert_allclose(vm.so3_exp(e[3:]), Ra @ Rb.T, atol=1e-12)
        assert np.linalg.norm(e[3:]) <= np.pi + 1e-12
