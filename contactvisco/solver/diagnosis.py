"""Why a step failed for good: the message of the time loop's final failure, with the likely
cause read from the SNES reason and the scene, or, for a body held by friction alone, the
friction limit its tangential load exceeds (no quasistatic equilibrium then exists).
"""
from __future__ import annotations

import numpy as np

from contactvisco.fem import contact_state
from contactvisco.model.stability import stability_number
from contactvisco.solver.newton import NewtonFailure


def step_failure(problem, comm, t_from, t_to, cuts, err: NewtonFailure, table,
                 step: int) -> NewtonFailure:
    """The failure of the step from t_from to t_to (after `cuts` halvings), with the friction
    limit when that explains it, else the likely cause. `table`: the contact table of the
    last equilibrium (None before the first); `step`: the number of accepted states.
    Collective."""
    limit = friction_limit(problem, comm, table)
    cut_note = f" after {cuts} cuts" if cuts else ""
    where = (f"the initial state (t = {t_to:g})" if t_from == t_to else
             f"step to t = {t_to:g} (from t = {t_from:g}{cut_note})")
    return NewtonFailure(
        f"{where}: "
        + (f"{limit}; {err}" if limit else
           f"{err}; {likely_cause(err, problem.scene, step)}")
        + force_control_note(problem, t_to),
        err.reason, err.residuals)


def force_control_note(problem, t: float) -> str:
    """With a force-controlled obstacle, what its Newton system solved for and what to change:
    the prescribed force at t, the obstacle's position at the last equilibrium and the keys
    (obstacle.force, time.steps). Empty without force control."""
    obstacle = problem.contact and problem.contact.obstacle
    if getattr(obstacle, "force_forms", None) is None:
        return ""
    force = np.round(obstacle.force_at(t), 12).tolist()
    last = obstacle.committed
    where = ("" if last is None else
             f"; the obstacle was at d = {np.round(last, 12).tolist()} at the last equilibrium")
    return (f". With obstacle.force: the Newton system bordered by the obstacle's position "
            f"(components {obstacle.controlled}) did not converge to the prescribed force "
            f"{force} at t = {t:g}{where}; give the force in smaller increments (more "
            f"time.steps, or a slower obstacle.force), or a force the body can carry")


def likely_cause(err: NewtonFailure, scene: dict, step: int) -> str:
    """A hint from the SNES reason and the scene."""
    if err.reason == -3:
        return ("likely cause: the linear solve failed; is the body held (Dirichlet conditions "
                "or a contact law with stiffness) against every rigid motion?")
    if err.reason == -4:
        return ("likely cause: the residual became NaN or Inf; check expressions for "
                "divisions by zero or overflow, and extreme parameter values")
    if err.reason == -5:
        hint = "likely cause: too large a step for the contact state to settle"
        if step > 0 and scene["time"]["rule"] == "paper" and \
                stability_number(scene) >= 1:
            hint += " (the paper's time rule is unstable at this step: use 'trapezoid')"
        return hint + "; try more time steps or raise -snes_max_it"
    return "see the residual history"


def friction_limit(problem, comm, previous) -> str | None:
    """Why a step of a body held by contact alone (no Dirichlet condition) failed, when the
    reason is that it has no quasistatic equilibrium: the tangential part of the external load
    resultant F exceeds mu times its normal part, the most that friction on the total normal
    pressure can hold (mu F.nu >= sum_i w_i |sigma_tau,i|). nu: the contact normal at the last
    equilibrium `previous` (a contact table), weighted by the normal reaction. Collective.
    Returns the explanation, or None (also with a prescribed friction bound contact.p_tau,
    which has no coefficient mu to compare with)."""
    if problem.contact is None or problem.contact.lambda_tau is None or problem.bcs_u:
        return None
    if problem.scene["contact"].get("p_tau") is not None:
        return None
    known = previous is not None
    previous = previous if known else contact_state.contact_table(problem, comm)  # weights, normals
    w = previous["weight"] * (np.maximum(previous["reaction_nu"], 0.0) if known else 1.0)
    normal = np.sum(w[:, None] * previous["normal"], axis=0)
    if not np.linalg.norm(normal) > 0:
        normal = np.sum(previous["weight"][:, None] * previous["normal"], axis=0)
    normal /= np.linalg.norm(normal)
    F = problem.load_resultant()
    pressing = float(F @ normal)          # the load pushing the body onto Gamma_C (nu: outward)
    tangential = float(np.linalg.norm(F - pressing * normal))
    mu = problem.scene["contact"]["mu"]
    if isinstance(mu, str):             # mu(x, t): no single friction limit to compare with
        return None
    if tangential <= mu * max(pressing, 0.0) * (1 + 1e-9):
        return None
    note = ""
    if known:
        force = np.linalg.norm(np.sum(previous["weight"][:, None]
                                      * previous["sigma_tau_vector"], axis=0))
        note = f"; friction force {force:.6g} at the last equilibrium"
    return (f"no quasistatic equilibrium: the tangential load exceeds the friction limit "
            f"(tangential load {tangential:.6g} > mu x normal load = {mu:g} x {pressing:.6g} = "
            f"{mu * max(pressing, 0.0):.6g}{note}); reduce the tangential load, raise "
            "contact.mu, or hold the body with a Dirichlet condition")
