"""Properties of the range and null filters (eqs. 5, 9), rank-deficient cases included."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import virtmech as vm

# magnitudes a Jacobian has in SI units (zero, or 1e-3 .. 10): J^T W J squares them
finite = st.one_of(st.just(0.0), st.floats(1e-3, 10), st.floats(-10, -1e-3))


@st.composite
def jacobians(draw):
    """A (6, n) Jacobian, sometimes with repeated or zero columns (rank-deficient)."""
    n = draw(st.integers(1, 6))
    J = draw(arrays(np.float64, (6, n), elements=finite))
    kind = draw(st.sampled_from(["generic", "repeat", "zero", "planar"]))
    if kind == "repeat" and n > 1:
        J[:, -1] = J[:, 0] * draw(st.floats(-2, 2))
    elif kind == "zero":
        J[:, draw(st.integers(0, n - 1))] = 0.0
    elif kind == "planar":
        J[[2, 3, 4], :] = 0.0  # planar motion: no z, no rx, ry
    return J


weights = arrays(np.float64, 6, elements=st.one_of(st.just(0.0), st.floats(0.01, 10)))


def full_rank(J, W):
    H = J.T @ np.diag(W) @ J
    s = np.linalg.svd(H, compute_uv=False)
    return s.size > 0 and s.min() > 1e-8 * max(s.max(), 1e-300)


@settings(max_examples=300, deadline=None)
@given(jacobians(), weights)
def test_range_filter_is_idempotent(J, W):
    P = vm.range_filter(J, W)
    assert np.all(np.isfinite(P))
    np.testing.assert_allclose(P @ P, P, atol=1e-6 * max(1.0, np.abs(P).max()))


@settings(max_examples=300, deadline=None)
@given(jacobians(), weights)
def test_null_forces_do_no_work_along_free_motion(J, W):
    if not full_rank(J, W):
        return
    N = vm.null_filter(J, W)
    scale = max(1.0, np.abs(J).max()) * max(1.0, np.abs(N).max())
    np.testing.assert_allclose(J.T @ N, 0.0, atol=1e-8 * scale)


@settings(max_examples=300, deadline=None)
@given(jacobians(), weights)
def test_zero_weighted_axes_get_no_range_force(J, W):
    P = vm.range_filter(J, W)
    assert np.all(P[W == 0.0, :] == 0.0)


@settings(max_examples=300, deadline=None)
@given(jacobians())
def test_unweighted_filters_are_complementary_orthogonal_projectors(J):
    P = vm.range_filter(J, np.ones(6))
    N = vm.null_filter(J, np.ones(6))
    np.testing.assert_allclose(P + N, np.eye(6), atol=1e-12)
    # (forming J^T J squares the condition number: 1e-3 against 10 costs ~1e-8)
    np.testing.assert_allclose(P, P.T, atol=1e-6)
    np.testing.assert_allclose(P @ N, 0.0, atol=1e-6)
    # P projects onto the column space of J
    U, s, _ = np.linalg.svd(J, full_matrices=False)
    r = int(np.sum(s > 1e-5 * max(s.max(), 1e-300))) if s.size else 0
    np.testing.assert_allclose(P, U[:, :r] @ U[:, :r].T, atol=1e-6)


def test_full_weight_matrix_equals_diagonal_vector():
    rng = np.random.default_rng(3)
    J = rng.normal(size=(6, 3))
    W = np.array([1.0, 2.0, 0.0, 0.5, 0.5, 0.1])
    np.testing.assert_allclose(vm.range_filter(J, np.diag(W)), vm.range_filter(J, W), atol=1e-12)


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
