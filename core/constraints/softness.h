// How soft a constraint is, in the two vocabularies users bring:
// ODE's (ERP, CFM) and a spring's (frequency, damping ratio).
//
// Section 4.1-4.2 writes a row as  J v + b + c lambda = 0  with Baumgarte
// bias b = (beta / h) C. Solving for the impulse P = h lambda gives
//   (J M^-1 J^T + c / h) P = -(J v + (beta / h) C).
// We store gamma = c / h (velocity per unit impulse) beside the bias rate.
//
// Spring form (the paper's reference [3], Catto's soft constraints): a
// spring k = m w^2 and damper d = 2 m zeta w on a row of effective mass
// m = 1 / K_ii, integrated implicitly over h, is the same row with
//   beta  = h k / (h k + d)            = h w / (h w + 2 zeta)
//   c     = 1 / (h k + d)   so  gamma  = K_ii / (h w (h w + 2 zeta)).
// (From m dv = -h (k C' + d v') with C' = C + h v': rearranging into
// J v' + beta/h C + c lambda = 0.) The mass cancels in beta, so only gamma
// needs K_ii, which prepare() knows once the Jacobian is built.
//
// Step-scaled spring: the frequency is a fixed fraction of the step rate,
// hertz = stepFraction / h, so beta and gamma / K_ii are the same at every
// step size. With sub-steps this keeps the joint as stiff as the sub-step
// rate allows (../shared/SCENES.md: 0.25-0.4 / h_sub, damping ratio about
// 2); a fixed frequency plateaus however many sub-steps run. Unlike plain
// ERP it always carries damping (gamma > 0), which is what keeps warm-
// started, not fully converged sweeps from feeding Baumgarte's correction
// back into growing oscillation on high mass ratios.
//
// Stiffness form: a spring k (N/m or N m/rad) and damper d in absolute
// units, as ODE's manual reads an (ERP, CFM) pair chosen for step h:
//   k = ERP / (h CFM),  d = (1 - ERP) / CFM.
// At any other step h' it is the row ERP' = h' k / (h' k + d),
// CFM' = 1 / (h' k + d): the same physical spring when sub-stepping.
#pragma once

#include <algorithm>
#include <cmath>

#include "core/math/math.h"

namespace blockstep {

// A softness's rates at one step h, worked out once for all the rows that
// share it (Solver::finishBlock: a block's rows mostly share one, and the
// per-row divisions were a good part of preparing a cloth). The same
// operations as Softness::biasRate() and gamma(), so the same results.
struct SoftnessAtStep {
  double biasRate = 0.0;    // beta / h
  double gammaFixed = 0.0;  // gamma, when it does not scale with K
  double perK = 1.0;        // gamma = kDiag / perK, when it does (massRelative)
  bool massRelative = false;
  double gamma(double kDiag) const { return massRelative ? kDiag / perK : gammaFixed; }
  // gamma(h, 1.0): c of a spring relative to the row's mass.
  double gammaUnit() const { return massRelative ? 1.0 / perK : gammaFixed; }
};

struct Softness {
  enum class Mode : unsigned char { ErpCfm, Spring, StepSpring, Stiffness };
  Mode mode = Mode::ErpCfm;
  double erp = 0.2;    // Baumgarte beta, fraction of the error removed per step
  double cfm = 1e-5;   // ODE's constraint force mixing: row velocity per unit force
  double hertz = 0.0;  // spring frequency, Hz (Spring mode)
  double dampingRatio = 1.0;
  double stepFraction = 0.25;  // StepSpring: hertz * h
  double stiffness = 0.0;      // Stiffness: k, N/m (N m/rad for angular rows)
  double damping = 0.0;        // Stiffness: d, N s/m (N m s/rad)

  static Softness erpCfm(double erp, double cfm) {
    Softness s;
    s.mode = Mode::ErpCfm;
    s.erp = erp;
    s.cfm = cfm;
    return s;
  }
  static Softness spring(double hertz, double dampingRatio) {
    Softness s;
    s.mode = Mode::Spring;
    s.hertz = hertz;
    s.dampingRatio = dampingRatio;
    return s;
  }
  static Softness stepSpring(double stepFraction, double dampingRatio) {
    Softness s;
    s.mode = Mode::StepSpring;
    s.stepFraction = stepFraction;
    s.dampingRatio = dampingRatio;
    return s;
  }
  static Softness springDamper(double stiffness, double damping) {
    Softness s;
    s.mode = Mode::Stiffness;
    s.stiffness = stiffness;
    s.damping = damping;
    return s;
  }
  // The spring and damper an (ERP, CFM) pair stands for at step h (CFM > 0).
  static Softness fromErpCfmAt(double erp, double cfm, double h) {
    return springDamper(erp / (h * cfm), (1.0 - erp) / cfm);
  }
  static Softness rigid() { return erpCfm(0.2, 0.0); }

  bool valid() const {
    if (mode == Mode::ErpCfm) return erp >= 0.0 && erp <= 1.0 && cfm >= 0.0 && std::isfinite(cfm);
    if (mode == Mode::Stiffness) {
      return stiffness >= 0.0 && damping >= 0.0 && stiffness + damping > 0.0 &&
             std::isfinite(stiffness) && std::isfinite(damping);
    }
    if (mode == Mode::StepSpring) {
      return stepFraction > 0.0 && std::isfinite(stepFraction) && dampingRatio >= 0.0 &&
             std::isfinite(dampingRatio);
    }
    return hertz > 0.0 && std::isfinite(hertz) && dampingRatio >= 0.0 &&
           std::isfinite(dampingRatio);
  }

  // Bias rate beta / h (1/s) for step h.
  double biasRate(double h) const {
    if (mode == Mode::ErpCfm) return erp / h;
    if (mode == Mode::Stiffness) return stiffness / (h * stiffness + damping);
    const double hw = omegaH(h);
    return hw / (hw + 2.0 * dampingRatio) / h;
  }
  // gamma = c / h for a row whose K diagonal is kDiag.
  double gamma(double h, double kDiag) const {
    if (mode == Mode::ErpCfm) return cfm / h;
    if (mode == Mode::Stiffness) return 1.0 / (h * (h * stiffness + damping));
    const double hw = omegaH(h);
    return kDiag / (hw * (hw + 2.0 * dampingRatio));
  }
  // Whether gamma scales with the row's K (a spring relative to its mass).
  bool massRelative() const { return mode == Mode::Spring || mode == Mode::StepSpring; }
  SoftnessAtStep atStep(double h) const {
    SoftnessAtStep r;
    r.biasRate = biasRate(h);
    r.massRelative = massRelative();
    if (r.massRelative) {
      const double hw = omegaH(h);
      r.perK = hw * (hw + 2.0 * dampingRatio);
    } else {
      r.gammaFixed = gamma(h, 1.0);
    }
    return r;
  }
  // h times the angular frequency.
  double omegaH(double h) const {
    return 2.0 * kPi * (mode == Mode::StepSpring ? stepFraction : hertz * h);
  }
};

}  // namespace blockstep
