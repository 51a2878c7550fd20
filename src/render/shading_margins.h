#pragma once
// Margins of the shadow-ray rules, shared by shade_surface and the batch shader (batch_shade.h).

namespace rt {

// Margin on n.l (cosine, dimensionless) before the convex rule trusts that a shadow ray leaves
// the surface's front half-space: far above the ~1e-15 rounding of the double dot product and of
// the float32 direction the ray really carries, so only rays within 1e-6 rad of grazing are traced.
inline constexpr double kConvexFacingMargin = 1e-6;

// Relative shortening (of t, float32) of a shadow ray that retraces a camera ray towards a light at
// the eye: far above the few-ulp error with which intersectors compute the hit's own t, so the hit
// surface is never its own occluder; nothing else lies in between, the camera ray found it closest.
inline constexpr float kRetraceMargin = 0x1p-16f;

}  // namespace rt
