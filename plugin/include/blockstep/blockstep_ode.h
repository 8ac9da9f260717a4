/* blockstep for ODE programs: a drop-in stepper with ODE's own API style.
 *
 *   #include <blockstep/blockstep_ode.h>
 *   ...
 *   dWorldBlockStep(world, 1.0 / 60.0);   instead of dWorldQuickStep
 *
 * Link with -lblockstep_ode before -lode (pkg-config blockstep_ode, or
 * find_package(blockstep) and blockstep::ode in CMake). Unmodified
 * programs can run with LD_PRELOAD=libblockstep_ode.so instead; see the
 * README for the BLOCKSTEP_* variables.
 *
 * Every world starts following its quickstep iteration count
 * (dWorldSetQuickStepNumIterations): n iterations become n / 2 sub-steps
 * of one solve sweep and one relax sweep, so blockstep spends the sweeps
 * quickstep would. The setters below switch a world to explicit settings.
 */
#ifndef BLOCKSTEP_ODE_H
#define BLOCKSTEP_ODE_H

#include <ode/ode.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Steps world w by stepsize seconds with blockstep. Returns 1 when the world
 * was stepped: by blockstep, or, when the world holds a joint kind or
 * contact mode blockstep cannot model, by ODE's dWorldQuickStep (said once
 * on stderr; see dWorldGetBlockStepStats). Returns 0 on bad input (a
 * non-finite state, an invalid mass, a step size not in (0, 1] s): the
 * world is left as it was and dWorldGetBlockStepMessage says why. */
ODE_API int dWorldBlockStep(dWorldID w, dReal stepsize);

/* Solver presets. */
ODE_API void dWorldSetBlockFollowQuickStep(dWorldID w); /* the default */
ODE_API void dWorldSetBlockSubsteppedSolver(dWorldID w, int substeps);
ODE_API void dWorldSetBlockPaperSolver(dWorldID w, int iterations);

/* Individual settings (each one leaves follow-quickstep mode). Counts
 * outside 1 to 100,000 sweeps (relax: 0 to 100,000) or 1 to 1,000
 * sub-steps are refused with a message, the world keeping its setting.
 *
 * Threads: as with ODE (dInitODE2, dAllocateODEDataForThread), each thread
 * may make, set, step and destroy worlds of its own; worlds on different
 * threads step in parallel, each under its own lock. */
ODE_API void dWorldSetBlockIterations(dWorldID w, int iterations); /* sweeps per sub-step */
ODE_API int dWorldGetBlockIterations(dWorldID w);
ODE_API void dWorldSetBlockSubsteps(dWorldID w, int substeps);
ODE_API int dWorldGetBlockSubsteps(dWorldID w);
ODE_API void dWorldSetBlockRelaxIterations(dWorldID w, int iterations);
ODE_API int dWorldGetBlockRelaxIterations(dWorldID w);
ODE_API void dWorldSetBlockTolerance(dWorldID w, dReal tolerance); /* m/s, 0: off */
ODE_API dReal dWorldGetBlockTolerance(dWorldID w);
ODE_API void dWorldSetBlockTimeBudget(dWorldID w, dReal seconds); /* 0: off */
ODE_API dReal dWorldGetBlockTimeBudget(dWorldID w);
ODE_API void dWorldSetBlockWarmStarting(dWorldID w, int on);
ODE_API int dWorldGetBlockWarmStarting(dWorldID w);
enum { dBlockModeBlock = 0, dBlockModeRowByRow = 1 };
ODE_API void dWorldSetBlockMode(dWorldID w, int mode);
ODE_API int dWorldGetBlockMode(dWorldID w);
ODE_API void dWorldSetBlockRecordResiduals(dWorldID w, int on);
/* Solve an island's joint equality rows as one exact block when it has at
 * most this many (0: one block per joint). Holds under every solver;
 * the default is the solver's own (192 rows sub-stepped and for
 * dWorldStep, 0 in the paper preset). BLOCKSTEP_ISLAND_BLOCK_ROWS. */
ODE_API void dWorldSetBlockIslandBlockRows(dWorldID w, int rows);
ODE_API int dWorldGetBlockIslandBlockRows(dWorldID w);
/* Solve an island of contacts (no joints, no bounce, no soft_cfm spring)
 * with at most this many contact points as one exact block: the points
 * that push, found by an active set, solved with the LDL^T of the
 * island's K, whatever the mass ratios (a 1000 kg block on a 1 kg plank
 * holds). 0: each contact's points one block, Gauss-Seidel between them.
 * Holds under every solver; the default is the solver's own (128 points
 * sub-stepped, 0 for dWorldStep and the paper preset).
 * BLOCKSTEP_CONTACT_ISLAND_ROWS. */
ODE_API void dWorldSetBlockContactIslandRows(dWorldID w, int rows);
ODE_API int dWorldGetBlockContactIslandRows(dWorldID w);
/* In a contact island not solved as one block (more points than that, a
 * pile; or joints in it), solve the contacts of each body three or more
 * times lighter than one it touches, and held by no joint, as one exact
 * block (1), or keep one block per contact (0). A light body pressed
 * between a heavy one and the ground then passes the load on at once.
 * Holds under every solver; the default is the solver's own (on
 * sub-stepped, off for dWorldStep and the paper preset).
 * BLOCKSTEP_LIGHT_BODY_GROUPS. */
ODE_API void dWorldSetBlockLightBodyGroups(dWorldID w, int on);
ODE_API int dWorldGetBlockLightBodyGroups(dWorldID w);
/* A contact found at the sub-step's start (blockstep's own collision
 * every sub-step, dWorldSetBlockCollision) on a body a joint holds gives
 * under the load it carries no more than under its own weight (1), or
 * its spring stays relative to its own mass (0): a light body carrying a
 * heavy jointed structure (a lattice's corner landing, a cloth over a
 * cube) is then pushed in. Holds under every solver; the default is the
 * solver's own (on sub-stepped, off for dWorldStep and the paper preset).
 * BLOCKSTEP_LOAD_RELATIVE_CONTACTS. */
ODE_API void dWorldSetBlockLoadRelativeContacts(dWorldID w, int on);
ODE_API int dWorldGetBlockLoadRelativeContacts(dWorldID w);
/* With blockstep's own collision every sub-step, in an island too large
 * to solve as one block, each fresh contact that would go more than this
 * depth (m) deeper within the sub-step if nothing pushed it gets the
 * contacts around it (on bodies no joint holds) solved as one exact
 * group: a box landing on a column of boxes of like mass. 0: off; the
 * default is the solver's own (1 mm sub-stepped, 0 for dWorldStep and
 * the paper preset). BLOCKSTEP_IMPACT_DEPTH. */
ODE_API void dWorldSetBlockImpactDepth(dWorldID w, dReal metres);
ODE_API dReal dWorldGetBlockImpactDepth(dWorldID w);
/* With blockstep's own collision every sub-step, in an island too large
 * to solve as one block, each fresh contact that would still go more than
 * this depth (m) deeper within the sub-step after the solver's sweeps gets
 * the contacts around it solved once more as one exact group, which stops
 * it sinking: a light body under a heavy load landing on it. 0: off; the
 * default is the solver's own (0.25 mm sub-stepped, 0 for dWorldStep and
 * the paper preset). BLOCKSTEP_SINKING_DEPTH. */
ODE_API void dWorldSetBlockSinkingDepth(dWorldID w, dReal metres);
ODE_API dReal dWorldGetBlockSinkingDepth(dWorldID w);
/* With blockstep's own collision every sub-step, parts are short enough
 * that a touching body's turn moves its shape's features (a box's corners,
 * a capsule's segment ends, a cylinder's rims) no farther than this (m)
 * within one, as well as no more than the turn per sub-step
 * (dWorldSetBlockMaxTurn, which must be on): a large shape's rim travels
 * farther in the same angle than a small one's. 0: the turn only; the
 * default is the solver's own (5 mm sub-stepped, 0 for dWorldStep and the
 * paper preset).
 * BLOCKSTEP_MAX_TRAVEL. */
ODE_API void dWorldSetBlockMaxTravel(dWorldID w, dReal metres);
ODE_API dReal dWorldGetBlockMaxTravel(dWorldID w);
/* With blockstep's own collision every sub-step, a part whose solve spins
 * a touching body past the turn per sub-step (dWorldSetBlockMaxTurn) is
 * taken again from its start, shorter, once (1), or kept (0); so is a part
 * whose solve sends a body farther than its collision reached (taken again
 * reaching farther). The default is the solver's own (on sub-stepped).
 * BLOCKSTEP_RETAKE_TURNS. */
ODE_API void dWorldSetBlockRetakeTurns(dWorldID w, int on);
ODE_API int dWorldGetBlockRetakeTurns(dWorldID w);
/* Cut an island with more joint rows than that (a cloth, a lattice) into
 * chains of joints, each of at most that many rows and solved as one
 * exact block inside the sweeps (1), or keep one block per joint (0, the
 * default). Holds under every solver. BLOCKSTEP_CHAIN_BLOCKS. */
ODE_API void dWorldSetBlockChainBlocks(dWorldID w, int on);
ODE_API int dWorldGetBlockChainBlocks(dWorldID w);
/* An island whose joints' rows are one exact block and that touches
 * something solves the normals of its jointed bodies' contacts in the
 * null space of those rows, with its limits and motors (1): a contact then stops
 * what the joints carry with its body, not only the body. Or its
 * contacts stay Gauss-Seidel partners of the joints (0, the default). Or
 * the former only in steps where one of its contacts is an impact, a
 * point closing faster than gravity alone closes it (2): a landing, not
 * a rest. Islands where that would cost too much a sweep keep the latter.
 * Holds under every solver. BLOCKSTEP_ISLAND_CONTACTS. */
ODE_API void dWorldSetBlockIslandContacts(dWorldID w, int mode);
ODE_API int dWorldGetBlockIslandContacts(dWorldID w);
/* More sub-steps while a jointed body turns fast: a step runs as many as
 * keep the fastest turn of a constrained body (over the last step) within
 * this angle per sub-step, up to 4 times the set count. Joints are
 * linearized in the turn, and a light link whipping through a 0.4 rad
 * sub-step opens its joints by millimetres at once. Holds under every
 * solver; the default is the solver's own (0.1 rad sub-stepped, 0 (off)
 * for dWorldStep and the paper preset). BLOCKSTEP_MAX_TURN. */
ODE_API void dWorldSetBlockMaxTurn(dWorldID w, dReal radians);
ODE_API dReal dWorldGetBlockMaxTurn(dWorldID w);
/* Sub-steps keep the rows, K and factors an earlier sub-step of the same
 * step prepared while no jointed body has turned more than this angle
 * since then (rad; 0: every sub-step prepares): each row's error follows
 * the bodies to first order. Steps with joint limits or motors, bouncing
 * contacts or moving surfaces prepare every sub-step. Holds under every
 * solver; the default is the solver's own (0.005 rad sub-stepped, 0 for
 * dWorldStep and the paper preset). BLOCKSTEP_REFRESH_TURN. */
ODE_API void dWorldSetBlockRefreshTurn(dWorldID w, dReal radians);
ODE_API dReal dWorldGetBlockRefreshTurn(dWorldID w);
/* 1: relax leaves each joint the velocity that closes the drift of its
 * linearized rows over the next sub-step (r (w h)^2 / 2 for a joint
 * turning at w), and a swinging chain keeps its energy (PyODE's tutorial2:
 * 99.6% over 10 s, against 84%); but a whipping chain's joints open wider
 * and can gain energy. 0 (default): relax targets J v = 0 and a chain
 * loses about (w h)^2 of its kinetic energy a sub-step. Holds under every
 * solver that relaxes. BLOCKSTEP_RELAX_DRIFT=0|1. */
ODE_API void dWorldSetBlockRelaxDrift(dWorldID w, int on);
ODE_API int dWorldGetBlockRelaxDrift(dWorldID w);
/* Position projections at the end of each step (post-stabilization): an
 * island whose joint equality rows are solved as one island block moves
 * its bodies so that its rigid joint rows close at the step's last pose,
 * this many times (0 to 16; 0: off); in an island that touches nothing,
 * what the moves lift against gravity the moved bodies' speed along them
 * pays. The ragdoll at
 * one sub-step a frame: joints 5.4 mm apart without, 0.005 mm with one.
 * Holds under every solver that makes joint rows rigid in island blocks
 * (the sub-stepped ones, which project once past 1 mm by default: see
 * dWorldSetBlockProjectionTolerance); the default is the solver's own.
 * BLOCKSTEP_PROJECTIONS=N. */
ODE_API void dWorldSetBlockProjections(dWorldID w, int projections);
ODE_API int dWorldGetBlockProjections(dWorldID w);
/* With projections on, an island whose rigid joint rows are all within
 * this error of closing at the step's pose (m, or rad for angular rows)
 * is not projected: it saves the island's factor at the pose where the
 * joints are already this close (0: every step projects; finite and >=
 * 0; the sub-stepped solvers' default is 1 mm). BLOCKSTEP_PROJECTION_TOLERANCE=E. */
ODE_API void dWorldSetBlockProjectionTolerance(dWorldID w, dReal error);
ODE_API dReal dWorldGetBlockProjectionTolerance(dWorldID w);
/* Threads that sweep a step's independent islands at once (TBB): 1 (the
 * default) the calling thread only, 0 one per core (never more than the
 * cores: a larger count is taken as that). Each island is swept
 * by one thread, so the result is bitwise the same whatever the count; a
 * world of one island gains little (only its bodies and blocks are
 * prepared in shares). BLOCKSTEP_THREADS=N. */
ODE_API void dWorldSetBlockThreads(dWorldID w, int threads);
ODE_API int dWorldGetBlockThreads(dWorldID w);
/* Sub-steps of an island of joints solved exactly: in the last step its
 * joints were one island block, projected at the step's end, and no
 * contact touched it, nor does one now (a hanging or swinging chain, a
 * star of particles, a hair strand clear of the head). Its joints hold at
 * any step, so it takes this many sub-steps (0 to 1000; 0: the step's
 * own count; 1 under the drop-in's settings, 0 otherwise), its turns
 * asking for no more (the projection closes what they open;
 * dWorldSetBlockMaxTurn must be on). At 1 a chain costs about what
 * quickstep 20 does, and an island turning less than 0.2 rad a step keeps
 * its energy (PyODE's double pendulum at 50 Hz keeps 99.9% in 10 s,
 * dWorldStep 75%); a whip turning faster loses more than at ten.
 * BLOCKSTEP_EXACT_JOINT_SUBSTEPS=N. */
ODE_API void dWorldSetBlockExactJointSubsteps(dWorldID w, int substeps);
ODE_API int dWorldGetBlockExactJointSubsteps(dWorldID w);
/* The same for an island of contacts only whose normals were solved as
 * one exact group (a stack, a plank under a load: up to
 * dWorldSetBlockContactIslandRows points): its load is carried at once
 * whatever the sub-steps; its fast turns still ask for more. The drop-in
 * takes 1 by default while the world follows quickstep's iteration
 * count; other solvers (dWorldSetBlockSubsteppedSolver among them) 0.
 * BLOCKSTEP_EXACT_CONTACT_SUBSTEPS=N. */
ODE_API void dWorldSetBlockExactContactSubsteps(dWorldID w, int substeps);
ODE_API int dWorldGetBlockExactContactSubsteps(dWorldID w);
/* Sub-steps of a calm island: one of joints that a contact holds, whose
 * joints were one island block in the last step (a ragdoll on the
 * ground, a car, a hair strand on the head; not a cloth cut into chains),
 * and that nothing strikes: no point of its contacts closes faster than
 * dWorldSetBlockCalmSpeed (m/s, default 0.3) at the step's start. One
 * turning too fast for this count takes the step's own. 0 to 1000; 0 (the
 * default): the step's own count. At 1 the thrown ragdoll steps in about
 * a fifth of the time, its joints within 1 mm, but its resting contacts
 * settle deeper and the ragdoll pile's tumbles go deeper (README, "Fewer
 * sub-steps for calm islands").
 * BLOCKSTEP_CALM_SUBSTEPS=N, BLOCKSTEP_CALM_SPEED=V. */
ODE_API void dWorldSetBlockCalmSubsteps(dWorldID w, int substeps);
ODE_API int dWorldGetBlockCalmSubsteps(dWorldID w);
ODE_API void dWorldSetBlockCalmSpeed(dWorldID w, dReal metresPerSecond);
ODE_API dReal dWorldGetBlockCalmSpeed(dWorldID w);
/* The runaway guard: an island whose kinetic energy grows beyond what its
 * forces, motors and position corrections explain by more than
 * energyGain (default 100, growth carried over steps), or in which a body
 * goes faster than maxSpeed m/s (default: no limit), or whose state turns
 * non-finite, is put back as it was before the step and stepped by ODE's
 * own stepper instead; said once on stderr naming its bodies and joints.
 * 0 turns a limit off (non-finite states are always caught).
 * BLOCKSTEP_RUNAWAY_GAIN, BLOCKSTEP_RUNAWAY_SPEED. */
ODE_API void dWorldSetBlockRunawayLimits(dWorldID w, dReal energyGain, dReal maxSpeed);
ODE_API void dWorldGetBlockRunawayLimits(dWorldID w, dReal* energyGain, dReal* maxSpeed);
/* Contact persistence: a body pair ODE's collider gives one or two
 * points that tip a body (a coin on its rim, a convex hull on a corner)
 * keeps its points of earlier steps while they stay within this distance
 * (m) of touching and of where they touched, up to four (default 0.005;
 * 0: off, every step solves exactly the contacts the program made).
 * BLOCKSTEP_CONTACT_PERSISTENCE. */
ODE_API void dWorldSetBlockContactPersistence(dWorldID w, dReal distance);
ODE_API dReal dWorldGetBlockContactPersistence(dWorldID w);

/* blockstep's own collision. From the next step on, blockstep collides
 * the geoms of `space` (and of the spaces inside it) itself: GJK/EPA for
 * every convex pair, manifolds of up to four points clipped from the
 * touching faces, speculative contacts within 2 cm, and, with
 * dBlockCollideEverySubstep in flags, collision again before every
 * sub-step rather than once per step. The contacts take `surface` as a
 * dContact's surface would (mode, mu, bounce, soft ERP/CFM; fdir1 is not
 * available). Geoms of bodies joined by a joint do not collide; ODE's
 * category and collide bits hold. Spheres, boxes, capsules, cylinders,
 * convex geoms and planes take part; other classes are left out (said
 * once). The program stops calling dSpaceCollide for that space; contact
 * joints it still makes are solved too. space NULL: off. */
enum { dBlockCollideEverySubstep = 1 };
ODE_API void dWorldSetBlockCollision(dWorldID w, dSpaceID space, const dSurfaceParameters* surface,
                                     int flags);

/* What the last dWorldBlockStep (or replaced step) of w did. */
enum {
  dBlockStepperNone = 0,      /* not stepped yet, or refused (bad input) */
  dBlockStepperBlockstep = 1, /* stepped by blockstep */
  dBlockStepperOde = 2        /* stepped by ODE: unsupported content */
};
typedef struct dBlockStepStats {
  int stepper;
  int substeps;
  int iterations; /* velocity sweeps, summed over sub-steps */
  int islands;
  int blocks;
  int rows;
  int residualCount; /* entries in the residual history */
  double solveSeconds;
  double stepSeconds;
  double collideSeconds; /* blockstep's own collision (dWorldSetBlockCollision) */
  /* Bodies of islands the runaway guard caught in this step (non-finite,
   * or kinetic energy far beyond what forces, motors and corrections
   * explain: dWorldSetBlockRunawayLimits): put back as they were before
   * the step and stepped by ODE's own stepper instead. */
  int handedToOde;
  /* Sub-steps that prepared their rows; the others kept an earlier
   * sub-step's (dWorldSetBlockRefreshTurn). */
  int preparedSubsteps;
} dBlockStepStats;
/* Returns 1 and fills stats, 0 for a world blockstep has not seen. */
ODE_API int dWorldGetBlockStepStats(dWorldID w, dBlockStepStats* stats);
/* The deepest contact point (m, >= 0) blockstep's own collision
 * (dWorldSetBlockCollision) found in the last step of w, at any of the
 * step's collisions (every sub-step with dBlockCollideEverySubstep): how
 * deep the solver let shapes go within the step, which a depth measured
 * after the step misses. 0 without that collision or before a step. */
ODE_API dReal dWorldGetBlockDeepestContact(dWorldID w);
/* Copies up to capacity residuals (largest and RMS over rows, per sweep)
 * of the last step; returns how many there were. Recorded while a
 * tolerance is set or dWorldSetBlockRecordResiduals is on. */
ODE_API int dWorldGetBlockResidualHistory(dWorldID w, dReal* maxima, dReal* rms, int capacity);
/* Records, from the next step of w on (on = 1) or no more (0), the
 * kinetic and potential energy (J) of the bodies blockstep steps at the
 * start of every sub-step and after each of its stages: where a step
 * gains or loses energy. The
 * step itself is the same. */
ODE_API void dWorldSetBlockRecordStageEnergy(dWorldID w, int on);
/* Stages: each sub-step's samples begin with its start, then follow in
 * the order the sub-step runs them. */
enum {
  dBlockStageForces = 0,    /* gravity, forces and damping added */
  dBlockStageWarmStart = 1, /* the last sub-step's impulses applied again */
  dBlockStageSweeps = 2,    /* the velocity sweeps, with position correction */
  dBlockStagePositions = 3, /* the positions moved */
  dBlockStageRelax = 4,     /* the bias-free sweeps */
  dBlockStageStart = 5,     /* the sub-step's start, before its forces */
  dBlockStageProjection = 6 /* the last pose projected onto the rigid joints (when it moved) */
};
/* Copies up to capacity samples of the last step of w, in the order they
 * were taken (any array may be NULL): the sub-step (0-based), the stage
 * (dBlockStage*), the kinetic energy and the potential energy in the
 * world's gravity. Islands that turn at different rates may be stepped
 * one after the other with their own sub-step counts, each summing its
 * own bodies: a change reads from one sample to the next within a
 * sub-step, from its start on. Returns how many samples there were (0
 * unless recording). */
ODE_API int dWorldGetBlockStageEnergy(dWorldID w, int* substep, int* stage, dReal* kinetic,
                                      dReal* potential, int capacity);
/* Why the last step of w was refused or fell back to ODE ("" if neither). */
ODE_API const char* dWorldGetBlockStepMessage(dWorldID w);

/* blockstep's collision as ODE's collider: from now on (or from
 * dInitODE, when called before it) every geom pair with a convex geom or
 * a cylinder that dCollide meets goes through blockstep's GJK/EPA and
 * face clipping (dSetColliderOverride), giving up to four contact points
 * where ODE's own paths give one. Whatever steps the world. ODE keeps no
 * copy of the colliders replaced: on = 0 once they are in place returns
 * 0 and leaves them until dCloseODE (the next dInitODE keeps ODE's own).
 * BLOCKSTEP_COLLIDERS=1 sets it at load. Returns 1 on success. */
ODE_API int dBlockSetColliders(int on);

/* Which ODE steppers go to blockstep: "all", "quickstep", "step" or
 * "none" (the default unless preloaded; BLOCKSTEP_REPLACE sets it at load).
 * Returns 0 for an unknown mode (nothing changes). */
ODE_API int dBlockStepSetReplace(const char* mode);

#ifdef __cplusplus
}
#endif

#endif /* BLOCKSTEP_ODE_H */
