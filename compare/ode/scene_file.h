// Scenes as data: a JSON file a built-in scene can be written to and a
// user's own scene read from (blockstep-compare --save-scenes, --scene-file).
//
// {
//   "name": "my_scene",
//   "gravity": [0, 0, -9.81], "erp": 0.2, "cfm": 1e-5,
//   "bodies": [
//     { "position": [x, y, z], "quaternion": [w, x, y, z],          (optional)
//       "linear_velocity": [..], "angular_velocity": [..],           (optional)
//       "mass": { "total": m, "center": [..], "inertia": [I11, I22, I33, I12, I13, I23] },
//       "geoms": [ { "type": "box", "size": [sx, sy, sz] },          (optional)
//                  { "type": "sphere", "radius": r },
//                  { "type": "capsule" | "cylinder", "radius": r, "length": l },
//                  ... each with optional "category_bits", "collide_bits" ] } ],
//   "static": [ { "type": "plane", "normal": [a, b, c], "offset": d },
//               { "type": "box", "size": [..], "position": [..], "quaternion": [..] } ],
//   "joints": [ { "type": "ball", "bodies": [i, j], "anchor": [..] },   (j = -1: the world)
//               { "type": "hinge", "bodies": [i, j], "anchor": [..], "axis": [..],
//                 "lo": -0.3, "hi": 0.8,                               (stops optional;
//                 "velocity": -4, "fmax": 100 },                         a motor, optional)
//               { "type": "fixed", "bodies": [i, j] },                 (fixed where they are)
//               { "type": "hinge2", "bodies": [i, j], "anchor": [..],      (a wheel: j turns about
//                 "steering": [..], "axle": [..], "lo": 0, "hi": 0,          the axle, steers about
//                 "suspension_erp": .4, "suspension_cfm": 1e-3,             the steering axis;
//                 "velocity2": 10, "fmax2": 30 } ],                          parameters optional)
//   "contact": { "mu": 0.6, "approx1": true, "bounce": [1, 0] },        (optional: every contact's
//                                                                         surface; mu -1: no limit)
//   "probe": k,                                                         (optional: drift of body k)
//   "draw": { "surface": { "columns": n, "bodies": [i, ...] },         (optional: how the report's
//             "strands": [ [i, j, ...], ... ] }                           replay draws the bodies)
// }
//
// "draw" tells the report's replay what the bodies stand for: a surface
// through a grid of bodies (row after row of `columns`; cloth), curves
// through strands of bodies (hair). Bodies are drawn by their geoms too.
//
// Capsules and cylinders lie along the body's z axis, as ODE makes them.
// Every error names the field: "bodies[3].mass.total: must be > 0".
#pragma once

#include <nlohmann/json.hpp>

#include <memory>
#include <string>

#include "compare/ode/scene.h"

namespace blockstep::compare {

nlohmann::json sceneToJson(const Scene& scene);
// Throws std::invalid_argument naming the bad field.
std::unique_ptr<Scene> sceneFromJson(const nlohmann::json& json);

void saveSceneFile(const Scene& scene, const std::string& path);
std::unique_ptr<Scene> loadSceneFile(const std::string& path);

}  // namespace blockstep::compare
