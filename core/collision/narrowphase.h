// Contact points between two posed shapes. Each function fills `m`
// (normal from the first shape toward the second, up to four points with
// their separations and the world positions midway between the surfaces)
// and returns the number of points; points farther apart than `margin`
// are left out (closer ones are speculative: they only stop approach).
#pragma once

#include "core/collision/shapes.h"
#include "core/constraints/contact.h"

namespace blockstep {

int collideSpherePlane(const Shape& plane, const Shape& sphere, const ShapePose& ps, double margin,
                       ContactManifold& m);
int collideBoxPlane(const Shape& plane, const Shape& box, const ShapePose& pb, double margin,
                    ContactManifold& m);
int collideSpheres(const Shape& a, const ShapePose& pa, const Shape& b, const ShapePose& pb,
                   double margin, ContactManifold& m);
int collideBoxSphere(const Shape& box, const ShapePose& pb, const Shape& sphere,
                     const ShapePose& ps, double margin, ContactManifold& m);
// Sphere or capsule against sphere or capsule: the closest points of the
// two core segments, and each segment end within the margin of the other.
// A cylinder against a capsule or cylinder the same way where their sides
// meet (a cylinder's ends: their rims); -1 where a cylinder's cap or rim
// is nearest or the two lie parallel: the caller takes GJK/EPA.
int collideRoundSegments(const Shape& a, const ShapePose& pa, const Shape& b, const ShapePose& pb,
                         double margin, ContactManifold& m);
// Separating-axis test over the 15 axes; face contacts clip the incident
// face against the reference face's sides (up to 8 points, reduced to 4),
// edge contacts give the closest points of the two edges.
int collideBoxes(const Shape& a, const ShapePose& pa, const Shape& b, const ShapePose& pb,
                 double margin, ContactManifold& m);

// Any two convex shapes (sphere, capsule, cylinder, box, hull): GJK on
// the cores when they are apart, EPA (libccd) when they overlap, then the
// manifold from the features touching along the normal found: the
// reference face (the one most along the normal) clips the incident
// feature, and the points within the margin are reduced to four.
int collideConvex(const Shape& a, const ShapePose& pa, const Shape& b, const ShapePose& pb,
                  double margin, ContactManifold& m);
// Any convex shape against a plane: its support point below the plane,
// and the points of its feature facing the plane (a hull: all its
// vertices) that lie within the margin.
int collideConvexPlane(const Shape& plane, const Shape& shape, const ShapePose& ps, double margin,
                       ContactManifold& m);

}  // namespace blockstep
