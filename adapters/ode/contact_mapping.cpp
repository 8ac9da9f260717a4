#include "adapters/ode/contact_mapping.h"

#include <algorithm>

namespace blockstep::ode {

WorldContactParams WorldContactParams::of(dWorldID world) {
  WorldContactParams p;
  p.erp = dWorldGetERP(world);
  p.cfm = dWorldGetCFM(world);
  p.maxCorrectingVelocity = dWorldGetContactMaxCorrectingVel(world);
  p.surfaceLayer = dWorldGetContactSurfaceLayer(world);
  return p;
}

MappedContact mapContact(const dContact& contact, BodyId body1, BodyId body2,
                         const WorldContactParams& world, double radius1, double radius2) {
  MappedContact out;
  out.unsupported =
      mapContactInto(contact, body1, body2, world, radius1, radius2, out.manifold, out.clamped);
  return out;
}

const char* mapContactInto(const dContact& contact, BodyId body1, BodyId body2,
                           const WorldContactParams& world, double radius1, double radius2,
                           ContactManifold& m, unsigned& clamped) {
  const char* unsupported = nullptr;
  const dSurfaceParameters& s = contact.surface;
  const int mode = s.mode;

  m.bodyA = body2;
  m.bodyB = body1;
  m.normal = Vec3(contact.geom.normal[0], contact.geom.normal[1], contact.geom.normal[2]);
  m.pointCount = 1;
  m.points[0].position = Vec3(contact.geom.pos[0], contact.geom.pos[1], contact.geom.pos[2]);
  m.points[0].separation = -contact.geom.depth;
  m.points[0].normal = m.normal;
  m.points[0].radiusA = radius2;
  m.points[0].radiusB = radius1;

  ContactSurface& c = m.surface;
  c.softness = Softness::erpCfm((mode & dContactSoftERP) ? s.soft_erp : world.erp,
                                (mode & dContactSoftCFM) ? s.soft_cfm : world.cfm);
  c.slop = world.surfaceLayer;
  c.maxCorrectingVelocity = world.maxCorrectingVelocity;
  if (mode & dContactBounce) {
    c.restitution = s.bounce;
    c.restitutionThreshold = s.bounce_vel;
    if (c.restitution < 0.0 || c.restitution > 1.0 || c.restitutionThreshold < 0.0) {
      c.restitution = std::clamp(c.restitution, 0.0, 1.0);
      c.restitutionThreshold = std::max(c.restitutionThreshold, 0.0);
      clamped |= kClampedContactBounce;
    }
  } else {
    c.restitution = 0.0;
    c.restitutionThreshold = 0.0;
  }

  const bool approx1 = (mode & dContactApprox1_1) != 0;
  const bool approx2 = (mode & dContactApprox1_2) != 0;
  if (approx1 != approx2) {
    unsupported = "dContactApprox1_1 without dContactApprox1_2 (or the reverse)";
  }
  c.friction = approx1 ? ContactSurface::Friction::Box : ContactSurface::Friction::Force;
  c.mu = s.mu;
  c.mu2 = (mode & dContactMu2) ? s.mu2 : -1.0;
  if (mode & dContactFDir1)
    c.frictionDir1 = Vec3(contact.fdir1[0], contact.fdir1[1], contact.fdir1[2]);
  c.motion1 = (mode & dContactMotion1) ? s.motion1 : 0.0;
  c.motion2 = (mode & dContactMotion2) ? s.motion2 : 0.0;
  c.motionN = (mode & dContactMotionN) ? s.motionN : 0.0;
  c.slip1 = (mode & dContactSlip1) ? s.slip1 : 0.0;
  c.slip2 = (mode & dContactSlip2) ? s.slip2 : 0.0;

  if (mode & dContactRolling) {
    const double rho = s.rho;
    const double rho2 = (mode & dContactAxisDep) ? s.rho2 : rho;
    const double rhoN = (mode & dContactAxisDep) ? s.rhoN : rho;
    if (rho2 != rho) unsupported = "different rolling friction about the two tangents";
    if (!(mode & dContactApprox1_N) || !approx1) {
      unsupported = "rolling friction as a fixed torque (without dContactApprox1)";
    }
    c.rolling = rho;
    c.spinning = rhoN;
  }
  return unsupported;
}

namespace {

bool sameSurface(const ContactSurface& a, const ContactSurface& b) {
  return a.friction == b.friction && a.mu == b.mu && a.mu2 == b.mu2 &&
         a.frictionDir1 == b.frictionDir1 && a.rolling == b.rolling && a.spinning == b.spinning &&
         a.restitution == b.restitution && a.restitutionThreshold == b.restitutionThreshold &&
         a.softness.mode == b.softness.mode && a.softness.erp == b.softness.erp &&
         a.softness.cfm == b.softness.cfm && a.softness.stiffness == b.softness.stiffness &&
         a.softness.damping == b.softness.damping && a.softness.hertz == b.softness.hertz &&
         a.softness.stepFraction == b.softness.stepFraction &&
         a.softness.dampingRatio == b.softness.dampingRatio && a.slop == b.slop &&
         a.maxCorrectingVelocity == b.maxCorrectingVelocity && a.motion1 == b.motion1 &&
         a.motion2 == b.motion2 && a.motionN == b.motionN && a.slip1 == b.slip1 &&
         a.slip2 == b.slip2;
}

}  // namespace

void groupContacts(const std::vector<ContactManifold>& in, std::vector<ContactManifold>& out) {
  ContactGrouping scratch;
  groupContacts(in, out, scratch);
}

void groupContacts(const std::vector<ContactManifold>& in, std::vector<ContactManifold>& out,
                   ContactGrouping& scratch) {
  out.clear();
  // The points by body pair, each pair's in ODE's order: a point can only
  // join a manifold of its own pair, so each pair is grouped alone.
  auto& byPair = scratch.byPair;
  byPair.clear();
  for (std::size_t k = 0; k < in.size(); ++k) {
    const auto a = static_cast<std::uint32_t>(in[k].bodyA);
    const auto b = static_cast<std::uint32_t>(in[k].bodyB);
    byPair.emplace_back(std::uint64_t{a} << 32 | b, static_cast<std::int32_t>(k));
  }
  std::sort(byPair.begin(), byPair.end());
  // Which input each manifold is made of, decided before any is copied:
  // each is then written once, in the order of its first point.
  auto& made = scratch.manifolds;
  made.clear();
  for (std::size_t begin = 0; begin < byPair.size();) {
    std::size_t end = begin;
    while (end < byPair.size() && byPair[end].first == byPair[begin].first)
      ++end;
    scratch.pairManifolds.clear();
    for (std::size_t k = begin; k < end; ++k) {
      const std::int32_t index = byPair[k].second;
      const ContactManifold& c = in[index];
      ContactGrouping::Made* target = nullptr;
      for (const std::int32_t slot : scratch.pairManifolds) {
        ContactGrouping::Made& m = made[slot];
        const ContactManifold& first = in[m.inputs[0]];
        // Rolling and spinning act about the manifold's one normal.
        const bool along = first.normal.dot(c.normal) > 0.999 ||
                           (c.surface.rolling == 0.0 && c.surface.spinning == 0.0);
        if (m.pointCount < kMaxManifoldPoints && along && sameSurface(first.surface, c.surface)) {
          target = &m;
          break;
        }
      }
      if (!target) {
        scratch.pairManifolds.push_back(static_cast<std::int32_t>(made.size()));
        ContactGrouping::Made& m = made.emplace_back();
        m.inputs[0] = index;
        m.inputCount = 1;
        m.pointCount = c.pointCount;
        continue;
      }
      // Each input that joins brings at least one point while there is
      // room, so a manifold takes at most kMaxManifoldPoints inputs with
      // points (one without points brings nothing).
      if (c.pointCount > 0) {
        target->inputs[target->inputCount++] = index;
        target->pointCount = std::min(target->pointCount + c.pointCount, kMaxManifoldPoints);
      }
    }
    begin = end;
  }
  // In the order of their first points, as ODE made them.
  std::sort(made.begin(), made.end(),
            [](const ContactGrouping::Made& x, const ContactGrouping::Made& y) {
              return x.inputs[0] < y.inputs[0];
            });
  for (const ContactGrouping::Made& m : made) {
    ContactManifold& target = out.emplace_back(in[m.inputs[0]]);
    for (int j = 1; j < m.inputCount; ++j) {
      const ContactManifold& c = in[m.inputs[j]];
      for (int i = 0; i < c.pointCount && target.pointCount < kMaxManifoldPoints; ++i)
        target.points[target.pointCount++] = c.points[i];
    }
  }
}

}  // namespace blockstep::ode
