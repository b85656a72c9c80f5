"""The [viscoelastic] table: the material as relaxation moduli with Prony terms (shear and bulk,
or Young's modulus with a constant Poisson ratio), entered inline or from a CSV file, and
converted exactly to the material.E, material.nu and memory.terms of eq (7)
(contactvisco.model.viscoelastic.paper_form) before the scene is checked, so that the run
uses the memory machinery of the paper's form unchanged.

A scene with [viscoelastic] relaxation functions states its material there only: material.E,
nu, lambda, mu and the [memory] table are then derived, and giving them too is refused. A
table without relaxation functions holds a temperature and its shift function alone: the
material stays in [material] and [memory], whose kernel then runs in reduced time when it is a
recursion of exponentials (reduced_time_refusal says why the others are not).
"""
from __future__ import annotations

import math
import pathlib

from contactvisco.errors import SceneError
from contactvisco.model import time_grid
from contactvisco.model import viscoelastic as ve
from contactvisco.scene import prony_file
from contactvisco.scene.table import (MODULUS_RANGE, Key, Table, finite, modulus, number_list,
                                      one_of)

#: The keys of one relaxation function (viscoelastic.shear, bulk, young).
SERIES_KEYS = ("instantaneous", "long_term", "tau", "moduli", "fractions", "file", "values",
               "scale", "time_scale")

#: viscoelastic.shift: the shift functions a_T of time-temperature superposition.
SHIFTS = ("none", "wlf", "arrhenius", "table")

#: viscoelastic.shift_interpolation: log10 a_T between the points of a shift table, piecewise
#: linear or the monotone Hermite cubic of Fritsch and Carlson (model.viscoelastic).
SHIFT_INTERPOLATIONS = ("linear", "monotone_cubic")

#: |log10 a_T(T_ref)| of a shift table above which it is refused (a_T(T_ref) = 1 by definition).
SHIFT_TABLE_ZERO = 1e-12

#: Material keys that [viscoelastic] derives.
DERIVED_MATERIAL = ("E", "nu", "lambda", "mu")


def _series_table(x) -> bool:
    return x is None or isinstance(x, dict)


class Viscoelastic(Table):
    """shear and bulk, or young and nu: each relaxation function a table of SERIES_KEYS."""

    KEYS = {
        "shear": Key(None, _series_table, "a table {instantaneous or long_term, tau, moduli "
                                          "or fractions, or file}"),
        "bulk": Key(None, _series_table, "a table like viscoelastic.shear"),
        "young": Key(None, _series_table, "a table like viscoelastic.shear"),
        "nu": Key(None, lambda x: x is None or finite(x), "a finite number"),
        "T_ref": Key(None, lambda x: x is None or finite(x),
                     "a finite number (the temperature of the Prony terms)"),
        "temperature": Key(None),
        "shift": Key("none", one_of(*SHIFTS), "none, wlf, arrhenius or table"),
        "C1": Key(None, lambda x: x is None or finite(x), "a finite number"),
        "C2": Key(None, lambda x: x is None or (finite(x) and x > 0), "a number > 0"),
        "activation_energy": Key(None, lambda x: x is None or (finite(x) and x > 0),
                                 "a number > 0 (J/mol)"),
        "shift_temperatures": Key(None, lambda x: x is None or number_list(x),
                                  "a list of finite numbers (increasing temperatures)"),
        "shift_log10_aT": Key(None, lambda x: x is None or number_list(x),
                              "a list of finite numbers (log10 a_T at shift_temperatures)"),
        "shift_file": Key(None, lambda x: x is None or (isinstance(x, str) and x != ""),
                          "the name of a CSV file (temperature, log10 a_T)"),
        "shift_interpolation": Key("linear", one_of(*SHIFT_INTERPOLATIONS),
                                   "linear or monotone_cubic"),
    }

    def rules(self, scene):
        """The shift function's constants, a temperature only with a shift function (a
        number is checked here; an expression at each step, point by point), and a time step
        that keeps the trapezoid rule's operator positive."""
        self._shift_rules(scene)
        self._implicit_operator(scene)

    def _implicit_operator(self, scene) -> None:
        """With the trapezoid rule the step solves (A + k/2 R(0)) eps = ..., R(0) < 0 for a
        relaxing material: per part, the instantaneous modulus plus k/2 R(0) must stay > 0, or
        the discrete material has a negative stiffness (k in reduced time, k / a_T, for a
        constant temperature; a step cut halves k)."""
        time, memory = scene["time"], scene["memory"]
        if time["rule"] != "trapezoid" or memory["kernel"] != "prony" or self.thermal_only():
            return
        from contactvisco.model.material import lame_constants
        mat = scene["material"]
        lam, mu = lame_constants(mat["model"], mat["E"], mat["nu"])
        d = scene.dimension
        A = {"deviatoric": 2 * mu, "volumetric": d * lam + 2 * mu}
        k = time_grid.largest_step(time)     # [time] is checked after this table
        theta = self["temperature"]
        if k is None:
            return                                  # [time] refuses its grid itself
        if finite(theta) and self["shift"] != "none":
            k /= 10.0 ** float(ve.log10_shift(self, theta))
        elif theta is not None:
            return                                  # a field: not known before the run
        R0 = {}
        for term in memory["terms"]:
            R0[term["part"]] = R0.get(term["part"], 0.0) + term["alpha"]
        for part, r in R0.items():
            k_max = 2 * A[part] / -r if r < 0 else math.inf
            name = ("young" if self["young"] is not None else
                    "shear" if part == "deviatoric" else "bulk")
            self.need(k < k_max, name,
                      (f"time.steps = {time['steps']}: the step k = {k:.4g}"
                       if time["grid"] == "uniform" else
                       f"time.grid = '{time['grid']}': its largest step k = {k:.4g}")
                      + (" (in reduced time, k / a_T)" if theta is not None else "")
                      + f" makes the {part} stiffness of the trapezoid rule, A + k/2 R(0) = "
                      f"{A[part]:.4g} - {k / 2 * -r:.4g}, <= 0 (the relaxation terms are too "
                      f"fast for the step); take k < {k_max:.4g} (more time steps), or "
                      "time.rule = 'exponential' (each term integrated exactly over the step: "
                      "the stiffness stays >= the long-term modulus for every k)")

    def _shift_rules(self, scene) -> None:
        shift = self["shift"]
        needed = {"none": (), "wlf": ("T_ref", "C1", "C2"),
                  "arrhenius": ("T_ref", "activation_energy"),
                  "table": ("T_ref",)}[shift]
        for name in needed:
            self.need(self[name] is not None, name,
                      f"viscoelastic.shift = '{shift}' needs viscoelastic.{name}")
        for name in ("C1", "C2", "activation_energy"):
            self.need(self[name] is None or name in needed, name,
                      f"viscoelastic.{name} belongs to another shift function than "
                      f"viscoelastic.shift = '{shift}'")
        self.need(shift == "table" or self["shift_interpolation"] == "linear",
                  "shift_interpolation",
                  f"viscoelastic.shift_interpolation = '{self['shift_interpolation']}' "
                  f"interpolates a shift table (viscoelastic.shift = 'table'), not "
                  f"viscoelastic.shift = '{shift}'")
        if shift == "table":
            if getattr(self, "shift_points", None) is None:
                # A table built again from a loaded scene (check, solve, run) reads its points
                # as load did: the file relative to the scene file's folder.
                path = getattr(self.provenance, "path", None)
                self.read_shift_table(path.parent if path is not None else None)
            self._shift_table_rules()
        if shift == "arrhenius":
            self.need(self["T_ref"] > 0, "T_ref", "viscoelastic.T_ref must be > 0 (kelvin) "
                                                  "for the Arrhenius shift")
        theta = self["temperature"]
        if theta is None:
            return
        self.need(shift != "none", "temperature",
                  "viscoelastic.temperature needs a shift function (viscoelastic.shift = "
                  "'wlf', 'arrhenius' or 'table') to act on the relaxation times")
        self.expression("temperature", theta, scene.dimension)
        if finite(theta):
            error = ve.shift_error(self, theta)
            self.need(error is None, "temperature", str(error))
        reason = reduced_time_refusal(scene["memory"])
        self.need(reason is None, "temperature", f"viscoelastic.temperature: {reason}")

    def thermal_only(self) -> bool:
        """True for a table without relaxation functions (no shear, bulk or young): it gives
        a temperature and its shift function to the material of [material] and [memory]."""
        return all(self[name] is None for name in ("shear", "bulk", "young"))

    def read_shift_table(self, base: pathlib.Path | None) -> None:
        """The points of viscoelastic.shift = 'table' (inline, or read from shift_file relative
        to `base`) as the attribute shift_points = (temperatures, log10 a_T); None for the
        other shift functions or when the table is not given (the rules then say so)."""
        self.shift_points = None
        inline = [k for k in ("shift_temperatures", "shift_log10_aT") if self[k] is not None]
        if self["shift"] != "table":
            given = inline + (["shift_file"] if self["shift_file"] is not None else [])
            self.need(not given, given[0] if given else "shift",
                      f"viscoelastic.{given[0] if given else ''} is the table of viscoelastic."
                      f"shift = 'table', not of viscoelastic.shift = '{self['shift']}'")
            return
        if self["shift_file"] is not None:
            self.need(not inline, inline[0] if inline else "shift_file",
                      "viscoelastic.shift_file gives the shift table: leave out viscoelastic."
                      "shift_temperatures and shift_log10_aT")
            key = self.key("shift_file")
            try:
                path = prony_file.resolve_path(self["shift_file"], base, key)
                self.shift_points = prony_file.read_shift(path, key)
            except SceneError as err:
                self.fail("shift_file", str(err))
            return
        self.need(len(inline) == 2, "shift_temperatures",
                  "viscoelastic.shift = 'table' needs viscoelastic.shift_temperatures and "
                  "shift_log10_aT (two lists of numbers), or viscoelastic.shift_file")
        temps, logs = self["shift_temperatures"], self["shift_log10_aT"]
        for name, items in (("shift_temperatures", temps), ("shift_log10_aT", logs)):
            self.need(number_list(items), name, f"viscoelastic.{name} must be a list of "
                                                f"finite numbers, got {items!r}")
        self.need(len(temps) == len(logs), "shift_log10_aT",
                  f"viscoelastic.shift_temperatures and shift_log10_aT must have the same "
                  f"length, got {len(temps)} and {len(logs)}")
        self.shift_points = ([float(x) for x in temps], [float(x) for x in logs])

    def _shift_table_rules(self) -> None:
        """At least two points, temperatures increasing, |log10 a_T| within MAX_LOG10_SHIFT
        (a_T positive and finite), T_ref inside the table with log10 a_T(T_ref) = 0."""
        temps, logs = getattr(self, "shift_points", None) or ([], [])
        name = "shift_file" if self["shift_file"] is not None else "shift_temperatures"
        self.need(len(temps) >= 2, name, "viscoelastic.shift = 'table' needs at least two "
                                         f"points (temperature, log10 a_T), got {len(temps)}")
        self.need(len(temps) <= prony_file.MAX_SHIFT_ROWS, name,
                  f"viscoelastic: at most {prony_file.MAX_SHIFT_ROWS} points in the shift "
                  f"table, got {len(temps)}")
        for i in range(1, len(temps)):
            self.need(temps[i] > temps[i - 1], name,
                      f"viscoelastic.shift_temperatures[{i}] = {temps[i]!r} does not exceed "
                      f"the previous {temps[i - 1]!r}: the temperatures must increase, each "
                      "once")
        for i, v in enumerate(logs):
            self.need(abs(v) <= ve.MAX_LOG10_SHIFT, "shift_log10_aT" if name !=
                      "shift_file" else name,
                      f"viscoelastic.shift_log10_aT[{i}] = {v!r}: |log10 a_T| must be at most "
                      f"{ve.MAX_LOG10_SHIFT:g} (a_T positive and finite)")
        T_ref = float(self["T_ref"])
        self.need(temps[0] <= T_ref <= temps[-1], "T_ref",
                  f"viscoelastic.T_ref = {T_ref:g} must lie in the shift table's range "
                  f"[{temps[0]:g}, {temps[-1]:g}] (a_T(T_ref) = 1 defines the table)")
        at_ref = float(ve.log10_shift(self, T_ref))
        self.need(abs(at_ref) <= SHIFT_TABLE_ZERO, "T_ref",
                  f"the shift table gives log10 a_T(T_ref = {T_ref:g}) = {at_ref:.6g}; it must "
                  f"be 0 (within {SHIFT_TABLE_ZERO:g}: a_T(T_ref) = 1 by definition). Subtract "
                  f"{at_ref:.6g} from every log10 a_T, or give the T_ref of the table")

    def series(self, name: str, base: pathlib.Path | None) -> ve.PronySeries:
        """The checked Prony series of viscoelastic.<name> (a file read from `base`)."""
        spec = self[name]
        where = self.key(name)
        unknown = sorted(set(spec) - set(SERIES_KEYS))
        if unknown:
            self.fail(f"{name}.{unknown[0]}", f"{where}.{unknown[0]}: unknown key; a relaxation "
                                              f"function has {', '.join(SERIES_KEYS)}")
        ends = [k for k in ("instantaneous", "long_term") if spec.get(k) is not None]
        self.need(len(ends) == 1, name, f"{where} needs exactly one of instantaneous (phi(0)) "
                                        f"and long_term (phi_inf), got {ends or 'neither'}")
        end = ends[0]
        value = spec[end]
        self.need(finite(value) and value > 0 and modulus(value), f"{name}.{end}",
                  f"{where}.{end} must be a modulus > 0 in [{1 / MODULUS_RANGE:g}, "
                  f"{MODULUS_RANGE:g}], got {value!r}")
        kind = self._kind(name, spec)
        taus, values = self._terms(name, spec, kind, base)
        return self._checked(name, end, value, kind, taus, values)

    def _kind(self, name: str, spec: dict) -> str:
        where = self.key(name)
        given = [k for k in ("moduli", "fractions") if spec.get(k) is not None]
        if spec.get("file") is not None:
            self.need(not given and spec.get("tau") is None, f"{name}.file",
                      f"{where}.file gives the terms: leave out {where}.tau, moduli and "
                      "fractions")
            kind = spec.get("values", "moduli")
            self.need(one_of("moduli", "fractions")(kind), f"{name}.values",
                      f"{where}.values must be 'moduli' or 'fractions' (what the file's second "
                      f"column holds), got {kind!r}")
            return kind
        self.need(spec.get("values") is None, f"{name}.values",
                  f"{where}.values says what a file holds; without {where}.file give "
                  f"{where}.moduli or {where}.fractions")
        self.need(len(given) <= 1, f"{name}.fractions",
                  f"{where}: give moduli (absolute) or fractions (normalized), not both")
        if not given:
            self.need(spec.get("tau") in (None, []), f"{name}.tau",
                      f"{where}.tau needs {where}.moduli or {where}.fractions")
        return given[0] if given else "moduli"

    def _terms(self, name: str, spec: dict, kind: str, base) -> tuple[list, list]:
        where = self.key(name)
        for factor in ("scale", "time_scale"):
            value = spec.get(factor, 1.0)
            self.need(finite(value) and value > 0, f"{name}.{factor}",
                      f"{where}.{factor} must be a number > 0 (the factor from the file's "
                      f"units to the scene's), got {value!r}")
        if spec.get("file") is not None:
            key = f"{where}.file"
            try:
                path = prony_file.resolve_path(spec["file"], base, key)
                taus, values = prony_file.read(path, key)
            except SceneError as err:
                self.fail(f"{name}.file", str(err))
            scale = float(spec.get("scale", 1.0)) if kind == "moduli" else 1.0
            return ([float(spec.get("time_scale", 1.0)) * t for t in taus],
                    [scale * v for v in values])
        self.need(spec.get("scale") is None and spec.get("time_scale") is None,
                  f"{name}.scale", f"{where}.scale and time_scale convert a file's units; "
                                   "inline terms are in the scene's units")
        taus = spec.get("tau") or []
        values = spec.get(kind) or []
        for key, items in (("tau", taus), (kind, values)):
            self.need(isinstance(items, list) and all(finite(v) for v in items),
                      f"{name}.{key}", f"{where}.{key} must be a list of finite numbers, got "
                                       f"{items!r}")
        self.need(len(taus) == len(values), f"{name}.tau",
                  f"{where}.tau and {where}.{kind} must have the same length, got "
                  f"{len(taus)} and {len(values)}")
        self.need(len(taus) <= prony_file.MAX_TERMS, f"{name}.tau",
                  f"{where}: at most {prony_file.MAX_TERMS} terms, got {len(taus)}")
        return list(map(float, taus)), list(map(float, values))

    def _checked(self, name, end, value, kind, taus, values) -> ve.PronySeries:
        where = self.key(name)
        for i, tau in enumerate(taus):
            self.need(tau > 0, f"{name}.tau", f"{where}.tau[{i}] = {tau!r}: a relaxation time "
                                              "must be > 0")
        for i, v in enumerate(values):
            self.need(v > 0, f"{name}.{kind}",
                      f"{where}.{kind}[{i}] = {v!r}: a Prony {kind[:-1]} must be > 0 (a "
                      "negative modulus has no physical meaning; leave a zero term out)")
        order = sorted(range(len(taus)), key=taus.__getitem__)
        for a, b in zip(order, order[1:]):
            self.need(taus[b] - taus[a] > ve.SAME_TIME * taus[b], f"{name}.tau",
                      f"{where}.tau[{a}] and tau[{b}] = {taus[a]!r}, {taus[b]!r}: terms with the "
                      "same relaxation time duplicate each other (add their moduli into one)")
        if kind == "fractions":
            total = sum(values)
            self.need(total < 1.0, f"{name}.fractions",
                      f"{where}.fractions sum to {total:.6g}: normalized Prony fractions must "
                      "sum to less than 1 (the long-term modulus phi(0) (1 - sum g_i) must be "
                      "> 0; at 1 or more the material creeps without bound)")
            out = ve.series(**{end: value}, taus=taus, fractions=values)
        else:
            out = ve.series(**{end: value}, taus=taus, moduli=values)
        self.need(out.long_term > 0 and out.long_term >= 1e-12 * out.instantaneous,
                  f"{name}.{end}",
                  f"{where}: the relaxed (long-term) modulus phi(0) - sum phi_i = "
                  f"{out.long_term:.6g} must be > 0 (at 0 or below the material creeps "
                  f"without bound); the instantaneous modulus is {out.instantaneous:.6g}")
        self.need(modulus(out.instantaneous), f"{name}.{end}",
                  f"{where}: the instantaneous modulus {out.instantaneous:.6g} must lie in "
                  f"[{1 / MODULUS_RANGE:g}, {MODULUS_RANGE:g}] (change the units)")
        return out

    def shear_bulk(self, model: str, base) -> tuple[ve.PronySeries, ve.PronySeries]:
        """G(t) and K(t), from shear and bulk or from young and nu (all checked)."""
        given = [k for k in ("shear", "bulk", "young") if self[k] is not None]
        if self["young"] is not None:
            self.need(given == ["young"], given[0] if given[0] != "young" else "shear",
                      "[viscoelastic] takes young (with nu) or shear and bulk, not both")
            nu = self["nu"]
            self.need(nu is not None and -1.0 < nu < 0.5, "nu",
                      f"viscoelastic.nu (constant in time) must lie in (-1, 0.5) with "
                      f"viscoelastic.young (the bulk modulus E / (3 (1 - 2 nu)) must be > 0, "
                      f"in plane stress too), got {nu!r}")
            return ve.young_series(self.series("young", base), float(nu))
        self.need(given == ["shear", "bulk"], "shear" if "shear" not in given else "bulk",
                  "[viscoelastic] needs shear and bulk (each a relaxation function; a table "
                  "without terms is elastic), or young and nu; got "
                  + (", ".join(given) or "none of them"))
        self.need(self["nu"] is None, "nu", "viscoelastic.nu goes with viscoelastic.young; "
                                            "with shear and bulk it follows from them")
        return self.series("shear", base), self.series("bulk", base)

    def convert(self, scene, base: pathlib.Path | None) -> None:
        """Set material.E, material.nu and the [memory] table of `scene` from the relaxation
        functions: A = the instantaneous moduli, R = their derivative (paper_form)."""
        model = scene["material"]["model"]
        self.read_shift_table(base)
        if self.thermal_only():
            self.need(self["nu"] is None, "nu", "viscoelastic.nu goes with viscoelastic.young")
            self.need(self["temperature"] is not None, "shear",
                      "[viscoelastic] needs shear and bulk (each a relaxation function; a "
                      "table without terms is elastic), or young and nu, or, for the material "
                      "of [material] and [memory], a temperature with its shift function; got "
                      "none of them")
            self.functions = {}           # the material stays in the paper's form
            return
        shear, bulk = self.shear_bulk(model, base)
        if model == "plane_stress" and not ve.proportional(shear, bulk):
            self.fail("bulk" if self["young"] is None else "young",
                      "material.model = 'plane_stress' with shear and bulk relaxing "
                      "differently is not converted: sigma_33 = 0 makes the in-plane bulk "
                      "modulus 9 K G / (3 K + 4 G), whose relaxation times are the zeros of "
                      "3 K~(s) + 4 G~(s) in Laplace variables, neither those of G nor of K. "
                      "Give proportional terms (the same tau_i and fractions in shear and "
                      "bulk), or viscoelastic.young with a constant nu, or use plane_strain or "
                      "3d")
        E, nu, terms = ve.paper_form(model, shear, bulk)
        # the functions as entered, for the figures (an attribute: not a scene key)
        self.functions = ({"young": self.series("young", base)} if self["young"] is not None
                          else {"shear": shear, "bulk": bulk})
        scene["material"]["E"], scene["material"]["nu"] = E, nu
        memory = scene["memory"]
        memory["kernel"] = "prony" if terms else "none"
        memory["terms"] = [{"alpha": a, "tau": tau, "part": part} for a, tau, part in terms]


#: Kernels whose history runs as a recursion of exponentials (the fractional kernel's older
#: steps; its last step integrated exactly over the reduced step), so in reduced time too.
REDUCED_TIME_KERNELS = ("none", "constant", "exponential", "prony", "power", "fractional")


def reduced_time_refusal(memory) -> str | None:
    """Why the memory kernel cannot run in reduced time, or None.

    Parameters
    ----------
    memory : dict
        The [memory] table.

    Returns
    -------
    str or None
        None for the kernels advanced by the recursion P_{n+1} = d P_n + dxi/2 (d e_n +
        e_{n+1}), d = exp(-dxi/tau_i) per point (Prony, exponential, constant and the power
        kernel as a sum of exponentials) and for the fractional kernel (its last step
        integrated exactly over dxi per point, older steps as a sum of exponentials); else the
        reason.
    """
    kernel = memory["kernel"]
    if kernel == "power" and memory["summation"] == "direct":
        return ("memory.summation = 'direct' sums the exact power kernel over every past step, "
                "R(t_{n+1} - t_j); in reduced time each point would need its own xi(t_{n+1}) - "
                "xi(t_j) for every past step j (O(n) memory per point), which is not kept: use "
                "memory.summation = 'soe' (a sum of exponentials, advanced by exp(-dxi/tau))")
    if kernel == "table":
        return ("memory.kernel = 'table' is convolved in full, R(t_{n+1} - t_j) summed over "
                "every past step (no recursion); in reduced time each point would need its "
                "own xi(t_{n+1}) - xi(t_j) for every past step j (O(n) memory per point), which "
                "is not kept: give the kernel as Prony terms (memory.kernel = 'prony')")
    if kernel == "fractional" and memory["summation"] == "direct":
        return ("memory.summation = 'direct' sums the exact fractional kernel over every past "
                "step; in reduced time each point would need its own xi(t_{n+1}) - xi(t_j) for "
                "every past step j (O(n) memory per point), which is not kept: use "
                "memory.summation = 'soe' (older steps as a sum of exponentials, advanced by "
                "exp(-dxi/tau))")
    return None


def _functions_given(raw: dict, assignments) -> bool:
    """Whether the scene's [viscoelastic] has a relaxation function (shear, bulk or young),
    in the file or by overrides."""
    names = ("shear", "bulk", "young")
    table = raw.get("viscoelastic")
    if isinstance(table, dict) and any(table.get(n) is not None for n in names):
        return True
    for path, value in assignments:
        if path[0] != "viscoelastic":
            continue
        if len(path) > 1 and path[1] in names:
            return True
        if len(path) == 1 and isinstance(value, dict) and any(n in value for n in names):
            return True
    return False


def check_alone(raw: dict, assignments) -> None:
    """[viscoelastic] derives material.E, nu (lambda, mu) and [memory]: giving them as well (in
    the file or by overrides) is refused, naming the key. A [viscoelastic] table without
    relaxation functions (a temperature and its shift only) goes with [material] and [memory].

    Parameters
    ----------
    raw : dict
        The scene as read.
    assignments : list
        The overrides as (path, value).
    """
    given = raw.get("viscoelastic") is not None or any(
        path[0] == "viscoelastic" for path, _ in assignments)
    if not given or not _functions_given(raw, assignments):
        return
    keys = [f"material.{k}" for k in (raw.get("material") or {}) if k in DERIVED_MATERIAL]
    keys += [f"memory.{k}" for k in (raw.get("memory") or {})]
    for path, value in assignments:
        if path[0] == "material" and len(path) == 2 and path[1] in DERIVED_MATERIAL:
            keys.append(".".join(path))
        elif path[0] == "material" and len(path) == 1 and isinstance(value, dict):
            keys += [f"material.{k}" for k in value if k in DERIVED_MATERIAL]
        elif path[0] == "memory":
            keys.append(".".join(path))
    if keys:
        raise SceneError(f"{keys[0]}: a scene with [viscoelastic] states its material there; "
                         f"material.E, nu, lambda, mu and [memory] are derived from it (give "
                         f"one form or the other)", key=keys[0])


def describe(scene) -> str | None:
    """The converted (A, R) of a scene with [viscoelastic], as the run prints it; else None.

    Parameters
    ----------
    scene : dict
        A resolved scene.

    Returns
    -------
    str or None
        A, as E, nu and the Lame constants, and R(t) term by term.
    """
    if scene.get("viscoelastic") is None or scene["viscoelastic"].thermal_only():
        return None
    from contactvisco.model.material import lame_constants
    mat = scene["material"]
    lam, mu = lame_constants(mat["model"], mat["E"], mat["nu"])
    lines = [f"viscoelastic: converted to eq (7): A with E = {mat['E']:.6g}, nu = "
             f"{mat['nu']:.6g} ({mat['model']}: lambda = {lam:.6g}, mu = {mu:.6g})"]
    terms = scene["memory"]["terms"] if scene["memory"]["kernel"] == "prony" else []
    if not terms:
        lines.append("  R = 0 (no Prony terms: elastic)")
    for t in terms:
        lines.append(f"  R += {t['alpha']:.6g} exp(-t/{t['tau']:.6g}) {t['part']}")
    return "\n".join(lines)
