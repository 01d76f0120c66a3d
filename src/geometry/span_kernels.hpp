// The arithmetic of a NURBS curve's span and a surface's span pair: the rational
// derivatives from the homogeneous shape's Taylor coefficients about the span's middle, an
// instance per degree (and usual derivative order) with its loops unrolled. Internal to the
// core.
#pragma once

#include "virtmech/geometry.hpp"

namespace virtmech::detail {

/// The derivatives (orders 0..nd) of a rational curve of degree p over one span at the
/// offset x from its middle, from the homogeneous curve's Taylor coefficients C there.
using SpanKernel = void (*)(const Eigen::Vector4d* C, double x, int p, int nd,
                            CurveDerivatives& out) noexcept;
/// The same for a rational surface of degrees (p, q) over one span pair at the offsets
/// (x, y), C indexed a * (q + 1) + b.
using SpanPairKernel = void (*)(const Eigen::Vector4d* C, double x, double y, int p, int q,
                                int nd, SurfaceDerivatives& out) noexcept;

/// The instance for degree p: a constant up to 5, else as given.
SpanKernel span_kernel(int p) noexcept;
/// The instance for degrees (p, q): constants up to 3 (the usual degrees), else as given.
SpanPairKernel span_pair_kernel(int p, int q) noexcept;

}  // namespace virtmech::detail
