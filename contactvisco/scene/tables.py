"""The tables of a scene, one class each: every key declared once (default, what is allowed,
meaning), the rules between keys in ``rules()``; :class:`Scene` holds them all.

A table is a dict of its values (``scene["contact"]["mu"]``) with its declarations in ``KEYS``,
its place in the scene (``path``: "contact", "dirichlet[1]") and the scene's provenance
(contactvisco.scene.table): a refused value raises a SceneError that carries the dotted key
and names its origin (a line of the scene file, a --set or load_scene override, or the
defaults), so no message is ever parsed to find a key.
"""
from __future__ import annotations

import ast
import copy
import math
import pathlib

import numpy as np

from contactvisco.errors import SceneError
from contactvisco.model.material import LAWS, dimension
from contactvisco.model.memory import PARTS, RULES
from contactvisco.model import time_grid
from contactvisco.model.memory_kernel import as_list
from contactvisco.scene.viscoelastic_table import Viscoelastic
from contactvisco.scene.table import (MODULUS_RANGE, Key, Provenance, Table, boolean, choice,
                                      choices, finite, integer, is_mesh_size, modulus,
                                      number_list, one_of, repeated)


#: Most cells a gmsh script may be asked for, estimated as (largest length / smallest size)^d.
MAX_SCRIPT_CELLS = 1e7

#: Most boxes (each 2 triangles or 6 tetrahedra) of a box geometry.
MAX_BOX_CELLS = 1e8

#: Most points of output.probes (each is read at every step and drawn in the figures).
MAX_PROBES = 1000

#: Default of output.max_bytes: the most a run may write (estimated before its first step).
MAX_OUTPUT_BYTES = 10e9

#: Most time steps of a grid (the memory of eq 19 is summed over all earlier steps).
MAX_STEPS = time_grid.MAX_STEPS

#: Largest growth of consecutive steps of a logarithmic grid (a decade per step).
MAX_GROWTH = 10.0


#: contact.friction_law: the friction ball's radius is mu p_nu(u_nu) or mu (p_nu(u_nu) + R_nu).
FRICTION_LAWS = ("compliance", "coulomb")
#: contact.friction_law's value when the scene gives none.
DEFAULT_FRICTION_LAW = "compliance"
#: contact.slip: the friction law acts on u_tau or on u_tau - u_tau(t_{n-1}).
SLIP_MEASURES = ("total", "increment")

#: Script parameters that are not extents of the body: a refinement distance, an angle in
#: degrees (the arc of a cylinder's contact boundary), the growth of a graded mesh's size
#: with the distance (a ratio).
NOT_EXTENTS = ("refine", "angle", "growth")


def _mesh_dir() -> pathlib.Path:
    """The gmsh scripts: installed inside the package, or meshes/ beside it in a source tree."""
    package = pathlib.Path(__file__).resolve().parent.parent
    installed = package / "meshes"
    return installed if installed.is_dir() else package.parent / "meshes"


#: Folder of the built-in mesh scripts (geometry.script names one of them).
MESH_DIR = _mesh_dir()


class Geometry(Table):
    KEYS = {
        "type": choice("box", "box", "gmsh"),
        "script": Key(None),
        "file": Key(None),
        "parameters": Key({}),
        "lower": Key([0.0, 0.0], lambda x: isinstance(x, list), "a list"),
        "upper": Key([1.0, 1.0], lambda x: isinstance(x, list), "a list"),
        "cells": Key([32, 32], lambda x: isinstance(x, list), "a list"),
        "diagonal": choice("right", "left", "right", "crossed", "left_right", "right_left"),
        "rotation": Key(0.0, finite, "a finite number of degrees"),
    }

    def rules(self, scene):
        d = scene.dimension
        if self["type"] == "box":
            self._box(scene["material"]["model"], d)
        else:
            self._gmsh(d)
        self.need(scene["material"]["model"] != "axisymmetric" or self["rotation"] == 0,
                  "rotation", f"geometry.rotation = {self['rotation']!r} has no meaning for "
                  "material.model = 'axisymmetric': the mesh lies in the half-plane "
                  "(r, z) = (x[0], x[1]), r >= 0, about the fixed z axis r = 0")

    def _box(self, model: str, d: int) -> None:
        lower, upper, cells = self["lower"], self["upper"], self["cells"]
        self.need(len(lower) == d and len(upper) == d and len(cells) == d, "cells",
                  f"geometry.lower, upper and cells need {d} entries for material.model = "
                  f"'{model}', got {lower}, {upper}, {cells}")
        self.need(all(integer(n) and n >= 1 for n in cells), "cells",
                  f"geometry.cells must be positive integers, got {cells}")
        self.need(math.prod(cells) <= MAX_BOX_CELLS, "cells",
                  f"geometry.cells = {cells} asks for {math.prod(cells):.3g} boxes (at most "
                  f"{MAX_BOX_CELLS:.0g}: the mesh is made on one rank before it is "
                  "distributed)")
        self.need(all(finite(a) and finite(b) and b > a for a, b in zip(lower, upper)), "upper",
                  f"geometry.upper must exceed geometry.lower, got {lower}, {upper}")
        self.need(all(abs(a) <= MODULUS_RANGE and abs(b) <= MODULUS_RANGE
                      and b - a >= 1 / MODULUS_RANGE for a, b in zip(lower, upper)), "upper",
                  f"geometry.lower and upper must lie within +-{MODULUS_RANGE:g} and be at "
                  f"least {1 / MODULUS_RANGE:g} apart (change the units), got {lower}, {upper}")

    def _gmsh(self, d: int) -> None:
        self.need((self["script"] is None) != (self["file"] is None), "type",
                  "geometry.type = 'gmsh' needs exactly one of geometry.script or geometry.file")
        if self["script"] is not None:
            self._script(d)
            return
        self.need(not (isinstance(self["file"], str)
                       and self["file"].endswith((".xdmf", ".h5", ".bp"))), "file",
                  f"geometry.file = {self['file']!r} is not a gmsh .msh file; a mesh of another "
                  "format is given through the Python interface: read it with DOLFINx and call "
                  "solve(scene, mesh=mesh, facet_tags=tags, boundaries={name: tag})")
        self.need(isinstance(self["file"], str) and self["file"].endswith(".msh"), "file",
                  f"geometry.file must be a gmsh .msh file, got {self['file']!r} (a .geo file "
                  "is a gmsh script, which can run commands: mesh it into a .msh first)")
        self.need(not self["parameters"], "parameters",
                  "geometry.parameters belong to a geometry.script; a geometry.file has none")

    def _script(self, d: int) -> None:
        """geometry.script names a built-in script of meshes/ (never a path), and its
        parameters are the script's, positive and finite, and not so fine that the mesh
        cannot be made."""
        scripts = sorted(p.stem for p in MESH_DIR.glob("*.py") if p.stem != "refinement")
        name = self["script"]
        self.need(isinstance(name, str) and name in scripts, "script",
                  f"geometry.script must be the name of a built-in mesh script "
                  f"({', '.join(scripts)}), not a path; got {name!r}")
        signature = script_signature(name)
        parameters = self["parameters"]
        self.need(isinstance(parameters, dict), "parameters",
                  f"geometry.parameters must be a table, got {parameters!r}")
        unknown = sorted(set(parameters) - set(signature))
        if unknown:
            self.fail(f"parameters.{unknown[0]}", f"geometry.parameters.{unknown[0]}: "
                                                   f"meshes/{name}.py has "
                                    f"no parameter {', '.join(unknown)}; it has "
                                    f"{', '.join(signature)}")
        for key, value in parameters.items():
            self.need(finite(value) and value > 0, f"parameters.{key}",
                      f"geometry.parameters.{key} must be a finite number > 0 (a length or a "
                      f"mesh size), got {value!r}")
        values = dict(signature, **parameters)
        sizes = {k: v for k, v in values.items() if is_mesh_size(k) and v is not None}
        lengths = [v for k, v in values.items() if not is_mesh_size(k) and v is not None
                   and k not in NOT_EXTENTS]
        if sizes and lengths:
            finest = min(sizes, key=sizes.get)
            cells = (max(lengths) / sizes[finest]) ** d
            self.need(cells <= MAX_SCRIPT_CELLS, f"parameters.{finest}",
                      f"geometry.parameters.{finest}: mesh size {sizes[finest]:g} for a body up "
                      f"to {max(lengths):g} long would make about {cells:.2g} cells (at most "
                      f"{MAX_SCRIPT_CELLS:.0g})")


def script_signature(name: str) -> dict:
    """Keyword parameters of build() in meshes/<name>.py with their default values, read from
    the script's syntax tree (nothing is run)."""
    tree = ast.parse((MESH_DIR / f"{name}.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.FunctionDef) and node.name == "build":
            names = [a.arg for a in node.args.args][1:]          # after gmsh
            defaults = [ast.literal_eval(v) for v in node.args.defaults]
            return dict(zip(names[len(names) - len(defaults):], defaults))
    return {}


class Material(Table):
    KEYS = {
        "model": choice("plane_strain", "plane_stress", "plane_strain", "3d", "axisymmetric"),
        "E": Key(1.0, lambda x: finite(x) and x > 0, "> 0"),
        "nu": Key(0.3),
        "lambda": Key(None),
        "mu": Key(None),
        # A nonlinear A (check_material_law): sigma = dW/deps.
        "law": choice("linear", *LAWS),
        "energy": Key(None),
        "hencky_exponent": Key(1.0, finite, "a finite number"),
        "hencky_strain": Key(0.01, lambda x: modulus(x) and x > 0,
                             f"> 0, in [{1 / MODULUS_RANGE:g}, {MODULUS_RANGE:g}]"),
    }
    MEANINGFUL_WHEN = {
        name: (lambda table, scene: table["law"] == "hencky", "with material.law = 'hencky'")
        for name in ("hencky_exponent", "hencky_strain")}

    def normalize(self) -> None:
        """lambda and mu given: E and nu from them (E = mu (3 lambda + 2 mu) / (lambda + mu),
        nu = lambda / (2 (lambda + mu)))."""
        lam, mu = self["lambda"], self["mu"]
        if lam is None and mu is None:
            return
        if not (finite(lam) and finite(mu) and mu > 0 and lam + mu > 0):
            self.fail("lambda" if mu is not None else "mu",
                      f"material.lambda and material.mu must both be given with mu > 0 and "
                      f"lambda + mu > 0, got lambda = {lam}, mu = {mu}")
        self["E"] = mu * (3 * lam + 2 * mu) / (lam + mu)
        self["nu"] = lam / (2 * (lam + mu))

    def rules(self, scene):
        self.need(modulus(self["E"]), "E", f"material.E must lie in [{1 / MODULUS_RANGE:g}, "
                                           f"{MODULUS_RANGE:g}] (change the units), got "
                                           f"{self['E']}")
        upper = 1.0 if self["model"] == "plane_stress" else 0.5
        self.need(finite(self["nu"]) and -1.0 < self["nu"] < upper, "nu",
                  f"material.nu must lie in (-1, {upper}) for {self['model']}, got "
                  f"{self['nu']}")
        check_material_law(self, scene)


#: The strain step h of check_material_law's differences of W at zero strain.
ENERGY_STEP = 1e-4


def check_material_law(table: Table, scene) -> None:
    """Check the nonlinear elasticity of material.law (material.energy, material.hencky_*).

    material.energy is an expression in tr_eps, eps2, dev_eps2, lmbda, mu_lame (and x, t);
    it is sampled at x = 0, t = 0 near zero strain: finite, stress-free at zero strain
    (|dW/deps| <= 1e-6 (2 mu) h by central differences of step h = ENERGY_STEP) and a
    positive definite tangent there (second differences along the symmetric unit strains and
    their pairwise sums > 0). Away from zero strain the tangent is checked where the solution
    takes it (contactvisco.fem.tangent). hencky_exponent must be > -1/2 (convex W).

    Parameters
    ----------
    table : contactvisco.scene.table.Table
        The [material] table.
    scene : Scene
        The scene (its dimension).

    Returns
    -------
    None
        A refused law raises a SceneError naming the key.
    """
    from contactvisco.model.material import invariants, lame_constants, strain_basis
    law = table["law"]
    if law == "hencky":
        table.need(table["hencky_exponent"] > -0.5, "hencky_exponent",
                   f"material.hencky_exponent must be > -1/2 (below, W is not convex: the "
                   f"deviatoric stress decreases with strain), got {table['hencky_exponent']}")
    table.need(law == "energy" or table["energy"] is None, "energy",
               "material.energy is the strain energy of material.law = 'energy': set "
               "material.law = 'energy' or drop material.energy")
    if law != "energy":
        return
    from contactvisco.scene.expressions import parse, value_at
    from contactvisco.model.material import ENERGY_NAMES
    text = table["energy"]
    table.need(isinstance(text, str), "energy",
               "material.law = 'energy' needs material.energy, an expression string in "
               f"{', '.join(ENERGY_NAMES)} (and x, t), e.g. "
               "'0.5 * lmbda * tr_eps**2 + mu_lame * eps2', got " + repr(text))
    from contactvisco.model.material import strain_dimension
    d = 3 if table["model"] == "3d" else 2            # of x
    try:
        parse(text, table.key("energy"), d, ENERGY_NAMES)
    except SceneError as err:
        table.fail("energy", str(err))
    lam, mu = lame_constants(table["model"], table["E"], table["nu"])
    key = table.key("energy")

    def W(eps):
        names = dict(invariants(eps), lmbda=lam, mu_lame=mu)
        return value_at(text, key, d, [0.0] * d, 0.0, names)

    basis = strain_basis(strain_dimension(table["model"]))
    directions = basis + [a + b for k, a in enumerate(basis) for b in basis[k + 1:]]
    h = ENERGY_STEP
    zero = W(np.zeros_like(basis[0]))
    for e in directions:
        plus, minus = W(h * e), W(-h * e)
        slope = (plus - minus) / (2 * h)
        table.need(abs(slope) <= 1e-6 * 2 * mu * h * np.sum(e * e), "energy",
                   f"material.energy = '{text}' gives a stress at zero strain (dW/deps : E = "
                   f"{slope:.3g} along E = {e.round(3).tolist()}): the reference state must "
                   "be stress-free (W without terms linear in the strain)")
        curvature = (plus - 2 * zero + minus) / h**2
        table.need(curvature > 0, "energy",
                   f"material.energy = '{text}' has a tangent that is not positive definite "
                   f"at zero strain (d^2W along E = {e.round(3).tolist()} is "
                   f"{curvature:.3g}): W must be convex (a positive definite A)")


KERNELS = ("none", "constant", "exponential", "prony", "table", "power", "fractional")


class Memory(Table):
    KEYS = {
        "kernel": choice("none", *KERNELS),
        "alpha": Key(0.0),
        "tau": Key([]),
        "beta": Key(0.5),
        "part": Key("full"),
        "tolerance": Key(1e-6),
        "summation": Key("soe"),
        "terms": Key([]),
        "times": Key([]),
        "values": Key([]),
    }

    def rules(self, scene):
        kernel = self["kernel"]
        if kernel in ("power", "fractional"):
            self._power(kernel)
        elif kernel == "constant":
            self.need(finite(self["alpha"]), "alpha",
                      f"memory.alpha must be a number, got {self['alpha']}")
        elif kernel == "exponential":
            self._exponential()
        elif kernel == "prony":
            self._prony()
        elif kernel == "table":
            self._table()

    def _exponential(self) -> None:
        alphas, taus = as_list(self["alpha"]), as_list(self["tau"])
        self.need(len(alphas) == len(taus) and len(taus) > 0, "tau",
                  "memory.alpha and memory.tau must have the same (non-zero) length")
        self.need(all(finite(t) and t > 0 for t in taus), "tau",
                  f"memory.tau must be > 0, got {taus}")
        self.need(all(finite(a) for a in alphas), "alpha",
                  f"memory.alpha must be numbers, got {alphas}")
        self.no_repeats("tau", taus, "the time scale",
                        "two terms with one tau are one term: give it once with the sum of "
                        "their alphas")

    def _prony(self) -> None:
        terms = self["terms"]
        self.need(isinstance(terms, list) and len(terms) > 0, "terms",
                  "memory.kernel = 'prony' needs memory.terms = [{alpha, tau, part}, ...]")
        for i, term in enumerate(terms):
            where = f"memory.terms[{i}]"
            self.need(isinstance(term, dict) and set(term) <= {"alpha", "tau", "part"}
                      and "alpha" in term, f"terms[{i}]",
                      f"{where} must be a table with alpha and optional tau, part; got {term}")
            self.need(finite(term["alpha"]), f"terms[{i}].alpha",
                      f"{where}.alpha must be a number")
            tau = term.get("tau", math.inf)
            self.need(isinstance(tau, (int, float)) and not isinstance(tau, bool) and tau > 0,
                      f"terms[{i}].tau", f"{where}.tau must be > 0 (inf: constant), got {tau}")
            self.need(term.get("part", "full") in PARTS, f"terms[{i}].part",
                      f"{where}.part must be full, deviatoric or volumetric")
        scales = [(term.get("tau", math.inf), term.get("part", "full")) for term in terms]
        found = repeated(scales)
        if found:
            i, j, (tau, part) = found
            self.fail(f"terms[{j}]", f"memory.terms lists the term tau = {tau!r}, part = "
                                     f"{part!r} twice (entries {i} and {j}): two terms with "
                                     "one tau and part are one term; give it once with the "
                                     "sum of their alphas")

    def _table(self) -> None:
        times, values = self["times"], self["values"]
        self.need(isinstance(times, list) and isinstance(values, list)
                  and len(times) == len(values) and len(times) >= 1, "times",
                  "memory.times and memory.values must have the same (non-zero) length")
        self.need(all(finite(v) for v in times + values), "values",
                  "memory.times and memory.values must be finite numbers")
        self.need(all(b > a for a, b in zip(times, times[1:])), "times",
                  "memory.times must increase")

    def _power(self, kernel: str) -> None:
        """R = alpha (1 + t/tau)^-beta P (power) or alpha t^-beta / Gamma(1 - beta) P
        (fractional), summed as exponentials to a relative tolerance."""
        self.need(finite(self["alpha"]), "alpha", f"memory.alpha must be a number for "
                                                  f"memory.kernel = '{kernel}', got "
                                                  f"{self['alpha']!r}")
        beta = self["beta"]
        if kernel == "power":
            self.need(finite(beta) and 0 < beta <= 20, "beta",
                      f"memory.beta must be a number in (0, 20] for the power kernel, got "
                      f"{beta!r}")
            self.need(finite(self["tau"]) and self["tau"] > 0, "tau",
                      f"memory.tau must be a number > 0 (the time scale of R = alpha "
                      f"(1 + t/tau)^-beta) for the power kernel, got {self['tau']!r}")
        else:
            self.need(finite(beta) and 0.01 <= beta <= 0.99, "beta",
                      f"memory.beta must lie in [0.01, 0.99] for the fractional kernel "
                      f"(t^-beta must be integrable at 0), got {beta!r}")
        tol = self["tolerance"]
        self.need(finite(tol) and 1e-12 <= tol <= 1e-2, "tolerance",
                  f"memory.tolerance must be a number in [1e-12, 1e-2] (relative error of the "
                  f"sum of exponentials), got {tol!r}")
        self.need(self["part"] in PARTS, "part", f"memory.part must be full, deviatoric or "
                                                 f"volumetric, got {self['part']!r}")
        self.need(self["summation"] in ("soe", "direct"), "summation",
                  f"memory.summation must be soe or direct, got {self['summation']!r}")




class Body(Table):
    """One [[body]] table: a part of the mesh (`cells`: a cell tag name of the mesh, or a
    region, an expression in x that is > 0 at the midpoints of the body's cells) with its own
    [material] and [memory] tables (the same keys; absent keys take the values of the scene's
    [material] and [memory])."""

    KEYS = {
        "name": Key(None),
        "cells": Key(None),
        "material": Key({}),
        "memory": Key({}),
    }
    REQUIRED = ("name", "cells")

    def resolve(self, scene) -> None:
        """material and memory as full Material and Memory tables: the keys the body gives,
        the others those of the scene's [material] and [memory] (E and nu given: not the
        scene's lambda and mu); an unknown key is a SceneError naming it."""
        for name, table in (("material", Material), ("memory", Memory)):
            given = self.get(name, {})
            self.need(isinstance(given, dict), name,
                      f"{self.key(name)} must be a table, got {given!r}")
            unknown = sorted(set(given) - set(table.KEYS))
            if unknown:
                self.fail(name, f"{self.key(name)}.{unknown[0]}: unknown key; allowed: "
                                f"{', '.join(table.KEYS)}")
            values = dict(scene[name])
            if name == "material" and ({"E", "nu"} & set(given)):
                values["lambda"] = values["mu"] = None
            values.update(copy.deepcopy(given))
            self[name] = table(values, self.key(name), self.provenance)

    def rules(self, scene):
        self.need(plain_name(self["name"]), "name",
                  f"{self.key('name')} must be a plain name, got {self['name']!r}")
        cells = self["cells"]
        self.need(isinstance(cells, str) and cells != "", "cells",
                  f"{self.key('cells')} must be a cell tag name of the mesh or a region (an "
                  f"expression in x, > 0 in the body), got {cells!r}")
        material, memory = self["material"], self["memory"]
        material.normalize()
        material.validate(scene)
        self.need(material["model"] == scene["material"]["model"], "material",
                  f"{self.key('material')}.model = {material['model']!r}: every body has the "
                  f"scene's model {scene['material']['model']!r}")
        self.need(material["law"] == "linear", "material",
                  f"{self.key('material')}.law = {material['law']!r}: a [[body]] takes the "
                  "linear A only")
        memory.validate(scene)


class Dirichlet(Table):
    """One [[dirichlet]] table: u = value on the boundary, for all or the listed components."""

    KEYS = {
        "boundary": Key(None),
        "components": Key("all", distinct=("the component", "a component prescribed twice "
                                          "leaves unsaid which value holds; list each once")),
        "value": Key(0.0),
    }
    REQUIRED = ("boundary",)

    def rules(self, scene):
        d = scene.dimension
        boundary_name(self)
        comps = self.get("components", "all")
        self.need(comps == "all" or (isinstance(comps, list) and all(
            integer(c) and 0 <= c < d for c in comps)), "components",
            f"{self.key('components')} must be 'all' or a list of components 0..{d - 1} of a "
            f"{d}D displacement, got {comps!r}")
        value = self.get("value", 0.0)
        if isinstance(value, list):
            count = d if comps == "all" else len(comps)
            self.need(len(value) == count, "value",
                      f"{self.key('value')} needs one entry per component ({count}), got "
                      f"{value!r}")
            for j, v in enumerate(value):
                self.expression("value", v, d, f"{self.key('value')}[{j}]")
        else:
            self.expression("value", value, d)


def boundary_name(table: Table) -> None:
    table.need(isinstance(table["boundary"], str), "boundary",
               f"{table.key('boundary')} must be a boundary name, got {table['boundary']!r}")


class Traction(Table):
    """One [[traction]] table: a surface load (a vector of d components) on a boundary."""

    KEYS = {
        "boundary": Key(None),
        "value": Key(None),
    }
    REQUIRED = ("boundary", "value")

    def rules(self, scene):
        d = scene.dimension
        boundary_name(self)
        value = self["value"]
        self.need(isinstance(value, list) and len(value) == d, "value",
                  f"{self.key('value')} must be a list of {d} components, got {value!r}")
        for j, v in enumerate(value):
            self.expression("value", v, d, f"{self.key('value')}[{j}]")


class BodyForce(Table):
    KEYS = {"value": Key(None)}

    def rules(self, scene):
        d = scene.dimension
        body = self["value"]
        self.need(body is None or (isinstance(body, list) and len(body) == d), "value",
                  f"body_force.value must be a list of {d} components, got {body!r}")
        for j, v in enumerate(body or []):
            self.expression("value", v, d, f"body_force.value[{j}]")


def nonnegative(x) -> bool:
    return finite(x) and x >= 0


#: contact.pairing: the projection of a master body's boundary onto the slave nodes.
PAIRINGS = ("mortar", "node_to_segment")


def _shape(scene) -> str:
    """obstacle.shape of a scene ("none" without an [obstacle] table)."""
    obstacle = scene.get("obstacle") if hasattr(scene, "get") else None
    return (obstacle or {}).get("shape") or "none"


class Contact(Table):
    """Normal compliance p_nu(s) = c_nu max(0, s) up to a layer g, then a rigid bound; friction
    bound mu p_nu (or mu times the total pressure); augmented-Lagrangian parameter r."""

    KEYS = {
        "boundary": Key("bottom", distinct=("the boundary", "a contact boundary listed twice "
                                           "would get the compliance twice; list each once")),
        "gap": Key(0.0),
        "stiffness": Key(0.0, nonnegative, "a finite number >= 0"),
        "g": Key(math.inf),
        # A number, or an expression in x and t (checked in rules()).
        "mu": Key(0.0, lambda x: nonnegative(x) or isinstance(x, str), "a finite number >= 0"),
        # None: DEFAULT_FRICTION_LAW, filled in by normalize() (after the former name).
        "friction_law": Key(None, one_of(*FRICTION_LAWS), choices(*FRICTION_LAWS)),
        "friction": Key(None),              # the former name of friction_law, read as it
        "slip": choice("total", *SLIP_MEASURES),
        "augmentation": Key(None, lambda x: finite(x) and x > 0, "> 0 (and finite)"),
        # Prescribed functions (eq 3), expressions in s (and p_nu): check_contact_laws.
        "p_nu": Key(None),
        "p_tau": Key(None),
        # Two deformable bodies ([obstacle] shape = "body"): how the slave nodes are paired
        # with the master boundary (contactvisco.fem.interface), and how far a slave node may
        # lie from it (None: a tenth of the mesh's extent).
        "pairing": choice("mortar", *PAIRINGS),
        "search_distance": Key(None, lambda x: x is None or (finite(x) and x > 0),
                               "a finite number > 0"),
        # The small-sliding limit of that pairing, made once in the reference configuration:
        # the fraction of its master facet a slave node may slide (inf: no check).
        "sliding_limit": Key(0.5, lambda x: (finite(x) and x > 0) or x == math.inf,
                             "a number > 0 (a fraction of the master facet), or inf"),
    }
    MEANINGFUL_WHEN = {
        name: (lambda table, scene: _shape(scene) == "body",
               "with a second body: obstacle.shape = 'body' and its obstacle.boundary")
        for name in ("pairing", "search_distance", "sliding_limit")}

    def normalize(self, material: dict) -> None:
        """g given as a text ("inf") read as a number; augmentation r defaults to the
        stiffness, or E if that is 0."""
        if isinstance(self["g"], str):
            try:
                self["g"] = float(self["g"])
            except ValueError:
                self.fail("g", f"contact.g must be a number >= 0 or inf, got {self['g']!r}")
        if self["augmentation"] is None:
            self["augmentation"] = self["stiffness"] or material["E"]
        self._read_former_friction()

    def _read_former_friction(self) -> None:
        """contact.friction, the former name of contact.friction_law, read as friction_law
        with the same values (and then dropped, so the scene holds friction_law only);
        friction_law unset: DEFAULT_FRICTION_LAW."""
        former = self.pop("friction", None)
        if former is not None:
            self.need(isinstance(former, str) and former in FRICTION_LAWS, "friction",
                      f"contact.friction must be {choices(*FRICTION_LAWS)}, got {former!r}")
            self.need(self["friction_law"] in (None, former), "friction",
                      f"contact.friction is the former name of contact.friction_law: give "
                      f"one of them, got friction = {former!r} and friction_law = "
                      f"{self['friction_law']!r}")
            self["friction_law"] = former
        if self["friction_law"] is None:
            self["friction_law"] = DEFAULT_FRICTION_LAW

    def rules(self, scene):
        names = self["boundary"]
        self.need(isinstance(names, str) or (isinstance(names, list) and names
                                             and all(isinstance(b, str) for b in names)),
                  "boundary", f"contact.boundary must be a boundary name or a list of names, "
                              f"got {names!r}")
        g = self["g"]
        self.need(isinstance(g, (int, float)) and not isinstance(g, bool) and g >= 0, "g",
                  f"contact.g must be >= 0 (inf: no bound), got {g}")
        for name in ("stiffness", "augmentation"):
            self.need(self[name] == 0 or modulus(self[name]), name,
                      f"contact.{name} must be 0 or lie in [{1 / MODULUS_RANGE:g}, "
                      f"{MODULUS_RANGE:g}] (change the units), got {self[name]}")
        self.expression("gap", self["gap"], scene.dimension)
        check_contact_laws(self, scene)
        compliance = self["stiffness"] > 0 or self["p_nu"] is not None
        self.need(compliance or math.isfinite(g), "stiffness",
                  "contact.stiffness: a contact boundary needs a compliance stiffness > 0 or a "
                  "finite bound g")
        if isinstance(self["mu"], str):
            self.expression("mu", self["mu"], scene.dimension)
        self.need(self["mu"] == 0 or self["friction_law"] == "coulomb"
                  or (compliance and g > 0), "mu",
                  f"contact.mu = {self['mu']} has no effect: the friction bound mu p_nu(u_nu) "
                  "is zero without a compliance stiffness > 0 and a layer g > 0; set "
                  "contact.mu = 0, or contact.friction_law = 'coulomb' for a bound mu times the "
                  "total normal pressure")


#: Sample points of check_contact_laws, as fractions of the sampled range [0, g]: two
#: points near 0 for the slope at 0+, then a uniform grid.
LAW_SAMPLES = (0.0, 1e-10, 1e-7) + tuple(k / 200 for k in range(1, 201))
#: The slope at 0+ is finite when p(h)/h at h = 1e-10 g exceeds its value at 1e-7 g by at
#: most this factor (p = c s^m: (1e-3)^(m - 1), 1.0007 for m = 0.9999).
LAW_SLOPE_RATIO = 1.0 + 1e-4


def check_contact_laws(table: Table, scene) -> None:
    """Check the prescribed functions contact.p_nu and contact.p_tau (paper eq 3).

    p_nu is an expression in the penetration s (and x, t), p_tau in s and p_nu (and x, t);
    the forms evaluate them at sigma = max(0, min(s, g)), so that they vanish for s < 0 and
    the friction bound at the bound is F_b = p_tau(g). What Newton needs is checked on
    samples of sigma in [0, g] ([0, 1] without a bound) at x = 0 and t = 0, T/2, T: finite
    values, p(0) = 0, p >= 0, p_nu non-decreasing and not zero, a finite slope at 0+ (s**0.5
    is refused: its derivative at 0 is infinite).

    Parameters
    ----------
    table : contactvisco.scene.table.Table
        The [contact] table (its p_nu, p_tau, stiffness, mu, g, friction_law).
    scene : Scene
        The scene (its dimension and time.T).

    Returns
    -------
    None
        A refused function raises a SceneError naming the key.
    """
    from contactvisco.scene.expressions import parse
    given = [name for name in ("p_nu", "p_tau") if table[name] is not None]
    if not given:
        return
    d = scene.dimension
    for name in given:
        table.need(isinstance(table[name], str), name,
                   f"contact.{name} must be an expression string in s (the penetration)"
                   f"{', p_nu' if name == 'p_tau' else ''}, x and t, e.g. "
                   f"{EXAMPLES[name]!r}, got {table[name]!r}")
        try:
            parse(table[name], table.key(name), d, ("s", "p_nu") if name == "p_tau" else ("s",))
        except SceneError as err:
            table.fail(name, str(err))
    if table["p_nu"] is not None:
        table.need(table["stiffness"] == 0, "p_nu",
                   "contact.p_nu and contact.stiffness are two forms of the normal law: give "
                   "one (stiffness c is p_nu = 'c * s')")
        table.need(table["g"] > 0, "p_nu",
                   "contact.p_nu acts in a compliant layer g > 0; with g = 0 (Signorini) the "
                   "normal law has no compliance: drop contact.p_nu")
    if table["p_tau"] is not None:
        table.need(table["mu"] == 0, "p_tau",
                   "contact.p_tau and contact.mu are two forms of the friction bound: give one "
                   "(mu is p_tau = 'mu * p_nu')")
        table.need(table["friction_law"] == "compliance", "p_tau",
                   "contact.p_tau is the bound p_tau(s) of friction_law = 'compliance' (the "
                   "paper's); with 'coulomb' the bound is mu times the total pressure: use "
                   "contact.mu")
        table.need((table["stiffness"] > 0 or table["p_nu"] is not None) and table["g"] > 0,
                   "p_tau", "contact.p_tau needs a normal compliance (contact.p_nu or "
                   "contact.stiffness > 0, and g > 0): there is no pressure to bound")
    upper = table["g"] if math.isfinite(table["g"]) else 1.0
    T = float(scene["time"]["T"]) if "time" in scene else 1.0
    for t in (0.0, T / 2, T):
        values = _sample_laws(table, d, upper, t)
        for name in given:
            _check_samples(table, name, values[name], upper, t)


EXAMPLES = {"p_nu": "2e3 * s**1.5", "p_tau": "0.3 * min(p_nu, 40)"}


def _sample_laws(table, d, upper, t) -> dict:
    """p_nu and p_tau at the samples sigma = upper * LAW_SAMPLES (lists of floats)."""
    from contactvisco.scene.expressions import value_at
    x = [0.0] * d
    p_nu, p_tau = [], []
    for fraction in LAW_SAMPLES:
        sigma = upper * fraction
        if table["p_nu"] is not None:
            p = value_at(table["p_nu"], table.key("p_nu"), d, x, t, {"s": sigma})
        else:
            p = table["stiffness"] * sigma
        p_nu.append(p)
        if table["p_tau"] is not None:
            p_tau.append(value_at(table["p_tau"], table.key("p_tau"), d, x, t,
                                  {"s": sigma, "p_nu": p}))
    return {"p_nu": p_nu, "p_tau": p_tau}


def _check_samples(table, name, values, upper, t) -> None:
    """The conditions of check_contact_laws on the samples of one function."""
    text = f"contact.{name} = '{table[name]}'"
    at = f"at x = 0, t = {t:g}"
    scale = max(abs(v) for v in values)
    tol = 1e-12 * scale
    table.need(abs(values[0]) <= tol, name,
               f"{text} gives {values[0]:g} at s = 0 ({at}): the law must vanish for s <= 0 "
               "(paper eq 3), so its value at 0 must be 0 (a jump at 0 has no derivative)")
    worst = min(range(len(values)), key=lambda k: values[k])
    table.need(values[worst] >= -tol, name,
               f"{text} is negative ({values[worst]:g}) at s = "
               f"{upper * LAW_SAMPLES[worst]:g} ({at}): the law must be >= 0")
    if name == "p_nu":
        table.need(scale > 0, name, f"{text} is zero on [0, {upper:g}] ({at}): no compliance")
        drops = [k for k in range(1, len(values)) if values[k] < values[k - 1] - tol]
        table.need(not drops, name,
                   f"{text} decreases near s = {upper * LAW_SAMPLES[drops[0]] if drops else 0:g}"
                   f" ({at}): p_nu must be non-decreasing (a monotone normal law)")
    h1, h2 = upper * LAW_SAMPLES[1], upper * LAW_SAMPLES[2]
    q1, q2 = values[1] / h1, values[2] / h2
    table.need(q1 <= LAW_SLOPE_RATIO * q2 + tol / upper, name,
               f"{text} has an infinite slope at s = 0+ (p(h)/h is {q2:.3g} at h = {h2:.3g} and "
               f"{q1:.3g} at h = {h1:.3g}, {at}): Newton's derivative at s = 0 would be "
               f"infinite; use powers s**m with m >= 1 (e.g. 'c * s**1.5'), or regularize "
               f"near 0 (e.g. 'c * s / sqrt(s + delta)' for c * s**0.5)")
#: obstacle.shape: the rigid obstacle's geometry ("none": the body's own normal and contact.gap).
OBSTACLE_SHAPES = ("none", "plane", "cylinder", "sphere", "cone", "punch", "surface", "body")

#: The shapes of revolution about a vertical axis, pressed downwards (2D only).
INDENTER_SHAPES = ("cone", "punch")


def _vector(x, d) -> bool:
    return number_list(x) and len(x) == d


def _takes(shape: str, d: int, name: str) -> bool:
    """Whether obstacle.shape = shape in d dimensions takes the key `name` (Obstacle.NEEDS)."""
    return name in Obstacle.NEEDS[shape] or (name == "axis" and shape == "cylinder" and d == 3)


class Obstacle(Table):
    """The rigid obstacle the contact boundary meets: its shape (a signed distance phi, > 0 on
    the body's side) and its prescribed rigid translation d(t). At a contact node x the gap is
    phi(x - d) and the contact direction nu = -grad phi (fem.obstacle)."""

    KEYS = {
        "shape": choice("none", *OBSTACLE_SHAPES),
        "point": Key(None),
        "normal": Key(None),
        "centre": Key(None),
        "radius": Key(None),
        "angle": Key(None),
        "axis": Key(None),
        "distance": Key(None),
        "displacement": Key(None),
        "force_components": Key([], lambda x: isinstance(x, list), "a list of components",
                                distinct=("the component", "a component controlled twice "
                                         "would get two forces; list each once")),
        "force": Key([], lambda x: isinstance(x, list), "a list of expressions in t"),
        # shape = "body": the master boundary, a facet tag name of the mesh.
        "boundary": Key(None),
    }

    #: The keys each shape needs (axis: a cylinder in 3D).
    NEEDS = {"none": (), "plane": ("point", "normal"), "cylinder": ("centre", "radius"),
             "sphere": ("centre", "radius"), "cone": ("point", "angle"),
             "punch": ("point", "radius"), "surface": ("distance",), "body": ("boundary",)}

    #: The shape's keys mean something only for the shapes that take them (NEEDS).
    MEANINGFUL_WHEN = {
        name: ((lambda table, scene, name=name: _takes(table["shape"], scene.dimension, name)),
               (lambda table, name=name: "with obstacle.shape = " + " or ".join(
                   f"'{s}'" for s in OBSTACLE_SHAPES if _takes(s, 2, name) or _takes(s, 3, name))
                + (" in 3D" if name == "axis" else "")
                + f" (this scene's obstacle.shape is '{table['shape']}')"))
        for name in ("point", "normal", "centre", "radius", "angle", "axis", "distance",
                     "boundary")}

    def rules(self, scene):
        shape, d = self["shape"], scene.dimension
        if shape == "none":
            given = [k for k in self.KEYS if k != "shape" and self[k] not in (None, [])]
            self.need(not given, given[0] if given else "shape",
                      f"obstacle.{given[0] if given else ''} is given but obstacle.shape is "
                      f"'none'; set obstacle.shape to {choices(*OBSTACLE_SHAPES[1:])}")
            return
        self.need(scene["contact"] is not None, "shape",
                  "an [obstacle] needs a [contact] table: the contact boundary it meets")
        self.need(scene["contact"]["gap"] == 0, "shape",
                  "an [obstacle] gives the gap itself (its distance to the contact nodes); "
                  "leave contact.gap at 0")
        needs = self.NEEDS[shape] + (("axis",) if shape == "cylinder" and d == 3 else ())
        for name in needs:
            self.need(self[name] is not None, name,
                      f"obstacle.shape = '{shape}' needs obstacle.{name}")
        for name in ("point", "normal", "centre", "axis"):
            if self[name] is not None:
                self.need(_vector(self[name], d), name,
                          f"obstacle.{name} must be a list of {d} finite numbers, got "
                          f"{self[name]!r}")
        for name in ("normal", "axis"):
            if self[name] is not None:
                length = math.sqrt(sum(v * v for v in self[name]))
                self.need(length > 0, name,
                          f"obstacle.{name} must have a non-zero length, got {self[name]!r}")
        if self["radius"] is not None:
            self.need(finite(self["radius"]) and self["radius"] > 0, "radius",
                      f"obstacle.radius must be a finite number > 0, got {self['radius']!r}")
        if self["angle"] is not None:
            self.need(finite(self["angle"]) and 0 < self["angle"] < 90, "angle",
                      "obstacle.angle (the cone's half-angle from its axis, in degrees) must be "
                      f"a number in (0, 90), got {self['angle']!r}")
        if shape in INDENTER_SHAPES:
            self.need(d == 2, "shape",
                      f"obstacle.shape = '{shape}' is an indenter in the (r, z) or (x, y) plane: "
                      "it needs a 2D mesh (axisymmetric, plane strain or plane stress); in 3D "
                      "give its distance with obstacle.shape = 'surface'")
        if self["distance"] is not None:
            self.need(isinstance(self["distance"], str), "distance",
                      f"obstacle.distance must be an expression in x (a signed distance), got "
                      f"{self['distance']!r}")
            self.expression("distance", self["distance"], d)
            self.need(not _uses_time(self["distance"]), "distance",
                      "obstacle.distance is the obstacle's shape in x; move it with "
                      "obstacle.displacement (expressions in t)")
        if shape == "body":
            self._body(scene)
        motion = self["displacement"]
        if motion is not None:
            self.need(isinstance(motion, list) and len(motion) == d, "displacement",
                      f"obstacle.displacement must be a list of {d} components (expressions "
                      f"in t), got {motion!r}")
            for j, value in enumerate(motion):
                where = f"obstacle.displacement[{j}]"
                self.expression("displacement", value, d, where)
                self.need(not isinstance(value, str) or not _uses_position(value),
                          "displacement", f"{where} = {value!r}: a rigid translation depends "
                                          "on t only, not on x")
        self._force(scene, d)
        if scene["material"]["model"] == "axisymmetric":
            self._axisymmetric()

    def _axisymmetric(self) -> None:
        """An axisymmetric body meets an obstacle of revolution about the z axis that moves
        along it: a sphere centred on the axis, a plane or a surface in (r, z); a cylinder
        (a torus about the axis) and another body (the pairing is 2D) are refused."""
        shape = self["shape"]
        self.need(shape not in ("cylinder", "body"), "shape",
                  f"obstacle.shape = '{shape}' has no axisymmetric version here: with "
                  "material.model = 'axisymmetric' use 'sphere' (centred on the axis), 'cone', "
                  "'punch', 'plane' or 'surface' (a distance in (r, z))"
                  + ("; two deformable bodies in axisymmetry are not supported "
                     "(docs/limitations.md)" if shape == "body" else ""))
        point = self["point"] if shape in INDENTER_SHAPES else None
        self.need(point is None or point[0] == 0, "point",
                  f"obstacle.point = {point!r}: with material.model = 'axisymmetric' a "
                  f"{shape}'s tip lies on the axis, point = [0, z] (r = 0)")
        centre = self["centre"]
        self.need(centre is None or centre[0] == 0, "centre",
                  f"obstacle.centre = {centre!r}: with material.model = 'axisymmetric' a "
                  "sphere is centred on the axis, centre = [0, z] (r = 0)")
        motion = self["displacement"]
        self.need(motion is None or motion[0] in (0, 0.0, "0"), "displacement",
                  f"obstacle.displacement = {motion!r}: with material.model = 'axisymmetric' "
                  "the obstacle moves along the axis only; give [0, d_z(t)]")
        self.need(0 not in self["force_components"], "force_components",
                  f"obstacle.force_components = {self['force_components']!r}: with "
                  "material.model = 'axisymmetric' a force acts along the axis only "
                  "(component 1, z), the radial resultant of a body of revolution being zero")

    def _body(self, scene) -> None:
        """shape = "body": the master boundary is a name other than the contact boundary; the
        master body moves with the solution, so it has no prescribed motion or force."""
        master, slave = self["boundary"], scene["contact"]["boundary"]
        self.need(isinstance(master, str) and master != "", "boundary",
                  f"obstacle.boundary must be a boundary name (the master body's), got "
                  f"{master!r}")
        slaves = [slave] if isinstance(slave, str) else list(slave)
        self.need(master not in slaves, "boundary",
                  f"obstacle.boundary = {master!r} is the contact boundary itself: the master "
                  "boundary must be another body's boundary")
        self.need(len(slaves) == 1, "boundary",
                  "obstacle.shape = 'body' pairs one contact boundary (contact.boundary, the "
                  f"slave) with obstacle.boundary, got contact.boundary = {slave!r}")
        for name in ("displacement", "force_components"):
            self.need(self[name] in (None, []), name,
                      f"obstacle.{name} has no meaning for obstacle.shape = 'body': the master "
                      "body moves with the solution")

    def _force(self, scene, d: int) -> None:
        """force_components: the components of d that are unknowns, their resultant contact
        force prescribed by force (one expression in t each)."""
        components, force = self["force_components"], self["force"]
        self.need(all(integer(c) and 0 <= c < d for c in components)
                  and len(set(components)) == len(components), "force_components",
                  f"obstacle.force_components must list distinct components 0..{d - 1}, got "
                  f"{components!r}")
        self.need(len(force) == len(components), "force",
                  f"obstacle.force needs one value per force-controlled component "
                  f"(obstacle.force_components = {components!r}), got {force!r}")
        for j, value in enumerate(force):
            where = f"obstacle.force[{j}]"
            self.expression("force", value, d, where)
            self.need(not isinstance(value, str) or not _uses_position(value), "force",
                      f"{where} = {value!r}: a resultant force depends on t only, not on x")
        if components:
            self.need(scene["discretization"]["contact_quadrature"] == "nodal"
                      and scene["solver"]["linear_system"] != "coupled", "force_components",
                      "obstacle.force_components: force control is solved with the condensed "
                      "Newton system (discretization.contact_quadrature = 'nodal', "
                      "solver.linear_system = 'auto' or 'condensed')")


def _names(text: str) -> set:
    return {node.id for node in ast.walk(ast.parse(text, mode="eval"))
            if isinstance(node, ast.Name)}


def _uses_time(text: str) -> bool:
    return "t" in _names(text)


def _uses_position(text: str) -> bool:
    return "x" in _names(text)


def _positive_or_none(x) -> bool:
    return x is None or (finite(x) and x > 0)


#: Keys of a segment of a piecewise grid (time.segments) and what each allows.
SEGMENT_KEYS = {
    "end": "a finite number > 0 (the segment's end time; the last one is time.T)",
    "grid": "uniform or logarithmic",
    "steps": "an integer >= 1 (the segment's uniform steps)",
    "first": "a number > 0 (the segment's first step)",
    "growth": f"a number > 1 and <= {MAX_GROWTH:g} (the ratio of consecutive steps)",
    "per_decade": "a number >= 1 (steps per decade of time)",
}


class Time(Table):
    """The time grid (contactvisco.model.time_grid), the rule of eq (19) and its stability."""

    KEYS = {
        "T": Key(1.0, lambda x: finite(x) and x > 0, "> 0"),
        "steps": Key(10, lambda x: integer(x) and x >= 1, "an integer >= 1"),
        "rule": choice("paper", *RULES),
        "allow_unstable": Key(False, boolean, "true or false"),
        "grid": choice("uniform", *time_grid.GRIDS),
        "first": Key(None, _positive_or_none, "a number > 0 (the first step, t_1)"),
        "growth": Key(None, lambda x: x is None or (finite(x) and 1 < x <= MAX_GROWTH),
                      f"a number > 1 and <= {MAX_GROWTH:g} (the ratio of consecutive steps)"),
        "per_decade": Key(None, lambda x: x is None or (finite(x) and x >= 1),
                          "a number >= 1 (steps per decade of time)"),
        "segments": Key(None, lambda x: x is None or (isinstance(x, list) and x and all(
            isinstance(v, dict) for v in x)), "a non-empty list of tables"),
        "times": Key(None, lambda x: x is None or (number_list(x) and x),
                     "a non-empty list of finite numbers"),
        "times_file": Key(None, lambda x: x is None or (isinstance(x, str) and x != ""),
                          "the name of a CSV file beside the scene file"),
        "times_column": Key(None, lambda x: x is None or (isinstance(x, str) and x != ""),
                            "the header name of the time column of time.times_file"),
        "tolerance": Key(None, lambda x: x is None or (finite(x) and 0 < x < 1),
                         "a number in (0, 1) (the relative local error of a step's memory)"),
        "min_step": Key(None, _positive_or_none, "a number > 0 (the adaptive grid's least step)"),
        "max_step": Key(None, _positive_or_none,
                        "a number > 0 (the adaptive grid's largest step)"),
        "landing_times": Key(None, lambda x: x is None or number_list(x),
                             "a list of finite numbers (times the adaptive grid lands on)"),
    }

    #: The keys of each grid kind besides T (a key of another kind is refused, not ignored).
    GRID_KEYS = {"uniform": (), "logarithmic": ("first", "growth", "per_decade"),
                 "piecewise": ("segments",), "times": ("times", "times_file", "times_column"),
                 "adaptive": ("first", "tolerance", "min_step", "max_step", "landing_times")}

    def rules(self, scene):
        kind = self["grid"]
        for other, names in self.GRID_KEYS.items():
            for name in names:
                self.need(name in self.GRID_KEYS[kind] or self[name] is None, name,
                          f"time.{name} belongs to time.grid = '{other}', not '{kind}'")
        if kind == "adaptive":
            self._adaptive(scene)
        if kind == "logarithmic":
            self._geometric(self, "time.grid = 'logarithmic'", "time.", self.need)
        elif kind == "piecewise":
            self._segments()
        elif kind == "times":
            self._times(scene)
        count = time_grid.count(self)
        name = {"uniform": "steps", "logarithmic": "first", "piecewise": "segments",
                "adaptive": "min_step",
                "times": "times" if self["times"] is not None else "times_file"}[kind]
        what = (f"time.steps = {self['steps']}" if kind == "uniform" else
                f"time.{name}: the grid has {count:.4g} steps, which")
        self.need(count <= MAX_STEPS, name,
                  f"{what} is more than {MAX_STEPS} steps (the memory of eq 19 sums over "
                  "every earlier step and each step writes its records): take fewer, larger "
                  "steps (time.rule = 'trapezoid' is second order)")
        self.grid_summary = time_grid.summary(self)
        least = self.grid_summary[1]
        self.need(least >= time_grid.LEAST_STEP * self["T"], name,
                  f"time.{name}: the grid's smallest step {least:.3g} is below "
                  f"{time_grid.LEAST_STEP:g} T = {time_grid.LEAST_STEP * self['T']:.3g} (two "
                  "step times that close are one time to the loop)")
        if not scene.get("body"):       # bodies: once their tables are checked (Scene)
            self.stable(scene)
        self._exponential_rule(scene)

    def _adaptive(self, scene) -> None:
        """An adaptive grid (contactvisco.solver.step_control): first and tolerance given,
        min_step <= first <= max_step <= T, landing_times inside (0, T); its estimate is the
        exponential rule's on a Prony history (no reduced time, no fitted or table kernel)."""
        for name in ("first", "tolerance"):
            self.need(self[name] is not None, name,
                      f"time.grid = 'adaptive' needs time.{name}")
        least, largest = time_grid.step_bounds(self)
        self.need(least <= self["first"] <= largest <= self["T"], "max_step",
                  f"time.grid = 'adaptive': min_step {least:g} <= first {self['first']:g} <= "
                  f"max_step {largest:g} <= T {self['T']:g} is not true")
        self.need(self["rule"] == "exponential", "rule",
                  "time.grid = 'adaptive' estimates the exponential rule's error: set "
                  "time.rule = 'exponential'")
        visco, kernel = scene.get("viscoelastic"), scene["memory"]["kernel"]
        self.need(kernel in ("constant", "exponential", "prony") or (
            kernel == "none" and visco is not None), "grid",
                  "time.grid = 'adaptive' needs a memory of exponential terms (memory.kernel "
                  f"constant, exponential or prony, or [viscoelastic]), not {kernel!r}")
        self.need(visco is None or visco["temperature"] is None, "grid",
                  "time.grid = 'adaptive' steps in time, not in the reduced time of "
                  "viscoelastic.temperature: use a logarithmic grid")

    @staticmethod
    def _geometric(spec, what: str, prefix: str, need) -> None:
        """A logarithmic grid or segment: its first step and one of growth, per_decade."""
        need(spec.get("first") is not None, "first",
             f"{what} needs {prefix}first (the first step, > 0)")
        given = [n for n in ("growth", "per_decade") if spec.get(n) is not None]
        need(len(given) == 1, given[1] if len(given) == 2 else "growth",
             f"{what} needs one of {prefix}growth (the ratio of consecutive steps) or "
             f"{prefix}per_decade (steps per decade: growth 10^(1/per_decade)), got "
             + (" and ".join(given) or "neither"))

    def _segments(self) -> None:
        """Each segment a table of SEGMENT_KEYS, ends increasing, the last one T."""
        segments, start = self["segments"], 0.0
        self.need(segments is not None, "segments",
                  "time.grid = 'piecewise' needs time.segments, a list of tables {end, steps} "
                  "or {end, grid = 'logarithmic', first, growth or per_decade}")
        for i, segment in enumerate(segments):
            where = f"time.segments[{i}]"

            def need(ok, name, message, i=i):
                self.need(ok, f"segments[{i}].{name}", message)
            for name in segment:
                need(name in SEGMENT_KEYS, name,
                     f"{where}.{name}: unknown key; a segment has {', '.join(SEGMENT_KEYS)}")
            end = segment.get("end")
            need(finite(end) and end > start, "end",
                 f"{where}.end must be a finite number above the segment's start {start:g} "
                 f"(the ends increase), got {end!r}")
            kind = segment.get("grid", "uniform")
            need(kind in time_grid.SEGMENT_GRIDS, "grid",
                 f"{where}.grid must be uniform or logarithmic, got {kind!r}")
            if kind == "uniform":
                need(integer(segment.get("steps")) and segment["steps"] >= 1, "steps",
                     f"{where} is uniform: it needs steps, an integer >= 1, got "
                     f"{segment.get('steps')!r}")
                for name in ("first", "growth", "per_decade"):
                    need(name not in segment, name,
                         f"{where}.{name} belongs to a logarithmic segment (grid = "
                         "'logarithmic'), not a uniform one")
            else:
                need("steps" not in segment, "steps",
                     f"{where}.steps belongs to a uniform segment, not a logarithmic one")
                self._geometric(segment, f"{where} is logarithmic:", f"{where}.", need)
                for name, test in (("first", _positive_or_none),
                                   ("growth", self.KEYS["growth"].test),
                                   ("per_decade", self.KEYS["per_decade"].test)):
                    need(test(segment.get(name)), name,
                         f"{where}.{name} must be {self.KEYS[name].allowed}, got "
                         f"{segment.get(name)!r}")
            start = end
        self.need(start == self["T"], f"segments[{len(segments) - 1}].end",
                  f"time.segments: the last segment ends at {start!r}, not at time.T = "
                  f"{self['T']!r} (the segments make the whole grid)")

    def _times(self, scene) -> None:
        """time.times or time.times_file (read here, relative to the scene file's folder):
        increasing, >= 0, at most T."""
        given = [n for n in ("times", "times_file") if self[n] is not None]
        self.need(len(given) == 1, given[-1] if given else "times",
                  "time.grid = 'times' needs one of time.times (a list) or time.times_file (a "
                  "CSV file beside the scene file), got " + (" and ".join(given) or "neither"))
        self.need(self["times_column"] is None or self["times_file"] is not None,
                  "times_column", "time.times_column names a column of time.times_file")
        if self["times_file"] is not None:
            from contactvisco.scene import prony_file
            base = getattr(self.provenance, "path", None)
            key = self.key("times_file")
            try:
                path = prony_file.inside_path(self["times_file"],
                                              base.parent if base is not None else None, key)
                self.file_times = prony_file.read_times(path, key, self["times_column"],
                                                        MAX_STEPS + 1)
            except SceneError as err:
                self.fail("times_file", str(err))
            values, name = self.file_times, "times_file"
        else:
            values, name = self["times"], "times"
            self.need(len(values) <= MAX_STEPS + 1, name,
                      f"time.times: more than {MAX_STEPS} times")
        bad = next((i for i, t in enumerate(values)
                    if t < 0 or (i and t <= values[i - 1])), None)
        self.need(bad is None, name,
                  f"time.{name}: the times must be >= 0 and increase; entry {bad} is "
                  f"{values[bad] if bad is not None else 0!r}")
        self.need(values[-1] <= self["T"], name,
                  f"time.{name}: the last time {values[-1]!r} is after time.T = "
                  f"{self['T']!r} (T ends the run: set it to the last time or later)")

    def stable(self, scene) -> None:
        """The paper's rule only where it is stable (model.stability: b < 1 step by step, b
        of the worst [[body]] when the scene has some), unless time.allow_unstable."""
        from contactvisco.model.stability import amplifies, steps_for_stability, worst_body
        steps = len(time_grid.steps(self))
        b, body = worst_body(scene)
        if self["rule"] != "paper" or not amplifies(b, steps) or self["allow_unstable"]:
            return
        where = "" if body is None else f" in body {body!r} (its material and memory)"
        if self["grid"] == "uniform":
            what, name = f"time.steps = {steps}", "steps"
            instead = f"use time.steps > {steps_for_stability(steps, b)}"
        else:
            k = time_grid.steps(self)
            mean = float(np.max(0.5 * (k[:-1] + k[1:]))) if len(k) > 1 else float(k[0])
            what, name = f"time.grid = '{self['grid']}' ({steps} steps)", "grid"
            instead = (f"make the mean of every two consecutive steps less than "
                       f"{mean / b:.3g} (b is the largest such mean's number; the largest "
                       f"mean is {mean:.3g} now)")
        self.fail(name,
                  f"{what}: the paper's time rule (time.rule = 'paper') is "
                  f"unstable here{where} (b = k R(0) (1 + nu) / E = {b:.3g} >= 1, the solution "
                  f"grows without bound); {instead}, "
                  "time.rule = 'trapezoid' or 'exponential', or set time.allow_unstable = "
                  "true to run it anyway")

    def _exponential_rule(self, scene) -> None:
        """time.rule = 'exponential' integrates each exponential of the kernel exactly: a
        kernel that is no sum of exponentials (a table, the power kernel summed directly) has
        none to integrate; the fractional kernel's product integration is that rule already."""
        if self["rule"] != "exponential":
            return
        memory = scene["memory"]
        kernel = memory["kernel"]
        self.need(kernel != "table", "rule",
                  "time.rule = 'exponential' integrates each exponential term of the kernel "
                  "exactly over a step; memory.kernel = 'table' has no exponential terms (its "
                  "R(t) is summed directly): use time.rule = 'trapezoid' or 'paper'")
        self.need(kernel != "power" or memory["summation"] != "direct", "rule",
                  "time.rule = 'exponential' integrates each exponential term of the kernel "
                  "exactly over a step; memory.summation = 'direct' sums the power kernel "
                  "itself: use memory.summation = 'soe' (the kernel as a sum of exponentials) "
                  "or time.rule = 'trapezoid'")


class Discretization(Table):
    KEYS = {
        "degree": Key(1, lambda x: integer(x) and x in (1, 2), "1 or 2"),
        "contact_quadrature": choice("nodal", "nodal", "gauss"),
    }


def petsc_value(x) -> bool:
    return isinstance(x, (str, int, float, bool))


#: The geometry parameters of the gmsh scripts that are mesh sizes (solver.first_iterate =
#: "coarse" multiplies them by solver.coarse_factor).
MESH_SIZES = ("h", "h_bottom", "h_contact", "h_far")


def coarse_start_refused(scene) -> str | None:
    """Why a scene's first iterates cannot come from a coarser mesh
    (contactvisco.solver.coarse_start), or None where they can: one body on contact, under
    prescribed loads and obstacle positions, on a mesh that can be made coarser."""
    geo = scene["geometry"]
    if scene["contact"] is None:
        return "needs contact (without it every step is one linear solve)"
    if not (geo["type"] == "box" or (geo.get("script") is not None and any(
            name in (geo.get("parameters") or {}) for name in MESH_SIZES))):
        return ("needs a mesh that can be made coarser: a box (cells) or a gmsh script with "
                f"a mesh size among its parameters ({', '.join(MESH_SIZES)}); a mesh read "
                "from a file has none")
    obstacle = scene.get("obstacle") or {}
    if _shape(scene) == "body" or obstacle.get("force_components"):
        return ("is for one body under prescribed loads and obstacle positions, not a "
                "second body (obstacle.shape = 'body') or a force-controlled obstacle "
                "(obstacle.force_components)")
    return None


class Solver(Table):
    KEYS = {
        "petsc_options": Key({}, lambda x: isinstance(x, dict), "a table"),
        "max_cuts": Key(4, lambda x: integer(x) and 0 <= x <= 20, "an integer from 0 to 20"),
        "linear_system": choice("auto", "auto", "condensed", "coupled"),
        "linear_solver": choice("auto", "auto", "direct", "iterative"),
        "predictor": choice("extrapolate", "extrapolate", "linear", "none"),
        "first_iterate": choice("auto", "auto", "previous", "coarse"),
        "coarse_factor": Key(4, lambda x: integer(x) and 2 <= x <= 16,
                             "an integer from 2 to 16"),
        "line_search": choice("auto", "auto", "nonmonotone", "none"),
    }

    def rules(self, scene):
        for name, value in self["petsc_options"].items():
            self.need(isinstance(name, str) and name.replace("_", "").isalnum()
                      and not name.startswith("_"), "petsc_options",
                      f"solver.petsc_options: '{name}' is not a PETSc option name (letters, "
                      "digits and _, without the leading '-')")
            self.need(petsc_value(value), f"petsc_options.{name}",
                      f"solver.petsc_options.{name} must be a string, number or boolean, got "
                      f"{value!r}")
        if self["first_iterate"] == "coarse":
            reason = coarse_start_refused(scene)
            self.need(reason is None, "first_iterate",
                      f"solver.first_iterate = 'coarse' {reason}; use 'previous' or 'auto'")
        if self["linear_system"] == "condensed" and scene["contact"] is not None:
            self.need(scene["discretization"]["contact_quadrature"] == "nodal",
                      "linear_system",
                      "solver.linear_system = 'condensed' needs "
                      "discretization.contact_quadrature = 'nodal' (the conditions must hold "
                      "node by node); use 'coupled' or 'auto'")


#: output.fields: the fields an XDMF file may hold.
FIELDS = ("u", "sigma", "history_stress", "lambda_nu", "lambda_tau", "stress_components",
          "von_mises", "contact_status", "contact")


class Output(Table):
    KEYS = {
        "probes": Key([], lambda x: isinstance(x, list), "a list of points"),
        "figure_times": Key([], number_list, "a list of any number of finite numbers"),
        "xdmf": Key(True, boolean, "true or false"),
        "fields": Key(["u", "sigma", "von_mises", "contact"], lambda x: isinstance(x, list) and all(
            isinstance(f, str) and f in FIELDS for f in x), f"a list of {', '.join(FIELDS)}"),
        "figures": Key(True, boolean, "true or false"),
        "snapshot_max_nodes": Key(200000, lambda x: (integer(x) and x >= 0) or x == math.inf,
                                  "an integer >= 0 or inf"),
        "checkpoint": Key(True, boolean, "true or false"),
        # The schedule: counted in accepted states (the step numbers of steps.jsonl, a cut
        # step's halves included); the final state always has its fields and checkpoint.
        "field_every": Key(1, lambda x: integer(x) and x >= 1,
                           "an integer >= 1 (the XDMF fields at every n-th step)"),
        "field_times": Key([], lambda x: number_list(x) and all(v >= 0 for v in x),
                           "a list of times >= 0"),
        "checkpoint_every": Key(1, lambda x: integer(x) and x >= 1,
                                "an integer >= 1 (a checkpoint at every n-th step)"),
        "checkpoint_seconds": Key(0, lambda x: finite(x) and x >= 0,
                                  "a number of seconds >= 0 (0: off)"),
        # The estimate of what a run writes (solver/check.py) is refused above this.
        "max_bytes": Key(MAX_OUTPUT_BYTES, lambda x: (finite(x) and x > 0) or x == math.inf,
                         "a number of bytes > 0, or inf for no limit"),
    }

    def rules(self, scene):
        d = scene.dimension
        for i, point in enumerate(self["probes"]):
            self.need(number_list(point) and len(point) == d, "probes",
                      f"output.probes[{i}] must be a list of {d} finite numbers, got {point!r}")
        self.need(len(self["probes"]) <= MAX_PROBES, "probes",
                  f"output.probes lists {len(self['probes'])} points, at most {MAX_PROBES} "
                  "(each is a column of every step record and a curve of the figures; for a "
                  "field over many points use output.fields)")
        self.no_repeats("probes", self["probes"], "the point", "list each point once")
        for name in ("fields", "figure_times", "field_times"):
            self.no_repeats(name, self[name], "the entry", "list each once")
        t_end = scene["time"]["T"]
        for i, t in enumerate(self["field_times"]):
            self.need(t <= t_end, "field_times",
                      f"output.field_times[{i}] = {t!r} is after the end of the run: it must "
                      f"lie in [0, time.T] = [0, {t_end:g}]")
        self.need(self["checkpoint_seconds"] == 0 or self["checkpoint_every"] == 1,
                  "checkpoint_seconds",
                  f"output.checkpoint_seconds = {self['checkpoint_seconds']!r} and "
                  f"output.checkpoint_every = {self['checkpoint_every']!r}: give one of them "
                  "(checkpoints by wall time, or every n steps), not both")


def label(x) -> bool:
    return x is None or isinstance(x, str)


class Units(Table):
    """Labels on figure axes only (no conversion), e.g. "mm", "N", "s"."""

    KEYS = {name: Key(None, label, 'a text label such as "mm"')
            for name in ("length", "force", "time")}


#: The tables of a scene, in the order they are checked (the material first: the dimension
#: of the other tables' vectors follows from it).
TABLES = {
    "material": Material, "viscoelastic": Viscoelastic, "geometry": Geometry,
    "discretization": Discretization,
    "body_force": BodyForce, "memory": Memory, "time": Time, "contact": Contact,
    "obstacle": Obstacle, "solver": Solver, "output": Output, "units": Units,
}

#: Lists of tables ([[dirichlet]], [[traction]], [[body]]) and the class of their items.
TABLE_LISTS = {"dirichlet": Dirichlet, "traction": Traction, "body": Body}


def plain_name(x) -> bool:
    """The name is the default output folder results/<name>: one plain folder name."""
    return (isinstance(x, str) and 0 < len(x) <= 100 and "/" not in x and "\\" not in x
            and x not in (".", "..") and x.isprintable())


class Scene(Table):
    """A whole scene: the top-level keys, its tables (one class each in TABLES) and the lists
    of tables in TABLE_LISTS. ``scene["contact"]`` is None for a scene without contact."""

    KEYS = {
        "name": Key("unnamed", plain_name,
                    "a plain folder name (1 to 100 printable characters, no '/' or '\\', not "
                    "'.' or '..', as it is the default output folder results/<name>)"),
        "description": Key("", lambda x: isinstance(x, str), "a string"),
        "preset": Key(None),
    }

    @classmethod
    def defaults(cls) -> dict:
        out = super().defaults()
        for name in ("geometry", "material", "memory"):
            out[name] = TABLES[name].defaults()
        out["dirichlet"] = []
        out["body_force"] = BodyForce.defaults()
        out["traction"] = []
        out["body"] = []
        out["contact"] = None
        out["viscoelastic"] = None          # absent: the material in the paper's form
        for name in ("obstacle", "time", "discretization", "solver", "output", "units"):
            out[name] = TABLES[name].defaults()
        return out

    @property
    def dimension(self) -> int:
        """The space dimension (contactvisco.model.material.dimension)."""
        return dimension(self)

    @classmethod
    def build(cls, values: dict, provenance: Provenance | None = None) -> "Scene":
        """The typed scene of a dict of plain values (defaults filled in); not yet checked."""
        scene = cls(values, "", provenance)
        for name, table in TABLES.items():
            value = scene[name]
            if name in ("contact", "viscoelastic") and value is None:
                continue
            scene.need(isinstance(value, dict), name,
                       f"{name} must be a table ([{name}] in TOML), got {value!r}")
            scene[name] = table(value, name, provenance)
        for name, table in TABLE_LISTS.items():
            items = scene[name]
            scene.need(isinstance(items, list) and all(isinstance(i, dict) for i in items),
                       name, f"{name} must be a list of tables ([[{name}]] in TOML), got "
                             f"{items!r}")
            scene[name] = [table(item, f"{name}[{i}]", provenance)
                           for i, item in enumerate(items)]
        for body in scene["body"]:
            body.resolve(scene)
        return scene

    def validate(self, scene=None) -> None:
        """Every table's keys and rules, the material first."""
        super().validate(self)
        for item in (item for name in TABLE_LISTS for item in self[name]):
            missing = [r for r in item.REQUIRED if r not in item]
            item.need(not missing, missing[0] if missing else "",
                      f"{item.path} needs {', '.join(missing)}")
            unknown = sorted(set(item) - set(item.KEYS))
            if unknown:
                item.fail(unknown[0], f"{item.path}.{unknown[0]}: unknown key; a "
                                      f"[[{item.path.split('[')[0]}]] table has "
                                      f"{', '.join(item.KEYS)}")
        for name in TABLES:
            if self[name] is not None:
                self[name].validate(self)
        for item in (item for name in TABLE_LISTS for item in self[name]):
            item.validate(self)
        self._repeated_boundaries()
        self._bodies()
        if self["body"]:
            self["time"].stable(self)

    def _bodies(self) -> None:
        """[[body]] names differ; contact between two bodies ([obstacle] shape = "body")
        needs them."""
        seen = {}
        for j, body in enumerate(self["body"]):
            if body["name"] in seen:
                body.fail("name", f"body[{seen[body['name']]}] and body[{j}] are both named "
                                  f"{body['name']!r}; give each body its own name")
            seen[body["name"]] = j

    def _repeated_boundaries(self) -> None:
        """A boundary in two [[traction]] tables would be loaded twice; in two [[dirichlet]]
        tables with a component in common, one value would override the other."""
        d = self.dimension
        for name, instead in (("traction", "give one [[traction]] table per boundary, with "
                                           "the sum of the loads as its value"),
                              ("dirichlet", "one value would override the other; give each "
                                            "component of a boundary once")):
            seen = {}
            for j, item in enumerate(self[name]):
                comps = item.get("components", "all")
                comps = set(range(d)) if comps == "all" else set(comps)
                for i, earlier in seen.get(item["boundary"], []):
                    common = comps & earlier if name == "dirichlet" else comps
                    if common:
                        item.fail("boundary", f"{name}[{i}] and {name}[{j}] both act on the "
                                              f"boundary {item['boundary']!r}"
                                  + (f" (component {sorted(common)[0]})" if name ==
                                     "dirichlet" else "") + f": {instead}")
                seen.setdefault(item["boundary"], []).append((j, comps))

    def locate(self, err: SceneError) -> SceneError:
        """`err` (raised while building) with the origin of its key appended, once."""
        if err.located or err.key is None or self.provenance is None:
            return err
        out = SceneError(f"{err}{self.provenance.origin(err.key)}", key=err.key, located=True)
        return out
