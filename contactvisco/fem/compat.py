"""The DOLFINx API where its versions differ: 0.5 (Debian 12) and 0.10/0.11 (PyPI, conda).

Every choice is made by what the installed modules offer (feature detection), never by a
version number, so any installation of a supported DOLFINx takes the same path. The rest of
the package calls these functions instead of the differing DOLFINx names.
"""
from __future__ import annotations

import functools
import inspect

import numpy as np
import ufl
from dolfinx import fem, geometry, io
from dolfinx.fem import petsc as fem_petsc
from petsc4py import PETSc

# ------------------------------------------------------------------ spaces and functions

#: DOLFINx >= 0.8 builds every space with fem.functionspace and a value shape.
_SHAPED_SPACES = hasattr(fem, "functionspace")


def scalar_space(mesh, family: str, degree: int):
    """The scalar space of a family ("CG" or "DG") and degree."""
    if _SHAPED_SPACES:
        return fem.functionspace(mesh, (_family(family), degree))
    return fem.FunctionSpace(mesh, (family, degree))


def vector_space(mesh, family: str, degree: int):
    """The vector space (gdim components) of a family ("CG" or "DG") and degree."""
    if _SHAPED_SPACES:
        return fem.functionspace(mesh, (_family(family), degree, (mesh.geometry.dim,)))
    return fem.VectorFunctionSpace(mesh, (family, degree))


def tensor_space(mesh, family: str, degree: int, shape: tuple | None = None):
    """The tensor space of a family ("CG" or "DG") and degree: gdim x gdim, or `shape` (the
    3 x 3 strain of an axisymmetric body on its 2D mesh)."""
    d = mesh.geometry.dim
    if _SHAPED_SPACES:
        return fem.functionspace(mesh, (_family(family), degree, shape or (d, d)))
    if shape is None:
        return fem.TensorFunctionSpace(mesh, (family, degree))
    return fem.TensorFunctionSpace(mesh, (family, degree), shape=shape)


def blocked_space(mesh, family: str, degree: int, size: int):
    """A space of vectors of `size` components (any size) of a family and degree."""
    if _SHAPED_SPACES:
        return fem.functionspace(mesh, (_family(family), degree, (size,)))
    return fem.VectorFunctionSpace(mesh, (family, degree), dim=size)


def _family(name: str) -> str:
    return {"CG": "Lagrange"}.get(name, name)


def is_discontinuous(space) -> bool:
    """Whether a space's element is discontinuous (DG)."""
    element = space.ufl_element()
    if hasattr(element, "discontinuous"):            # basix.ufl elements
        return bool(element.discontinuous)
    return element.family() in ("Discontinuous Lagrange", "DG", "DQ")


def element_degree(space) -> int:
    """The polynomial degree of a space's element."""
    degree = space.ufl_element().degree
    return int(degree() if callable(degree) else degree)


def interpolation_points(space) -> np.ndarray:
    """The reference points at which an Expression is evaluated to interpolate into space."""
    points = space.element.interpolation_points
    return points() if callable(points) else points


def expression(value, space):
    """An Expression of the UFL `value` at the interpolation points of `space`, with its
    derivatives applied first. DOLFINx 0.5 hands the kernel the constants of `value` as
    written, while the kernel, compiled after differentiation, takes only those that remain:
    a constant that appears only under a derivative (grad of x - c) drops out of the kernel
    but not out of the packed list, and the constants after it are read from its values.
    Applying the derivatives first makes both lists the same (DOLFINx 0.10 and later give
    the same values either way)."""
    value = ufl.algorithms.expand_derivatives(value)
    return fem.Expression(value, interpolation_points(space))


def petsc_vector(function) -> PETSc.Vec:
    """The PETSc vector that shares the (owned and ghost) values of a Function."""
    x = function.x
    return x.petsc_vec if hasattr(x, "petsc_vec") else function.vector


def cell_dofs(dofmap) -> np.ndarray:
    """The dofs of every local cell (ghosts included), one row per cell."""
    layout = dofmap.list
    if isinstance(layout, np.ndarray):
        return layout
    return layout.array.reshape(-1, dofmap.dof_layout.num_dofs)


def geometry_nodes(mesh) -> np.ndarray:
    """The geometry nodes of every local cell (ghosts included), one row per cell: an array
    from DOLFINx 0.8 on (``dofmaps[0]`` where ``dofmap`` is deprecated), an
    adjacency list before."""
    dofmaps = getattr(mesh.geometry, "dofmaps", None)
    if isinstance(dofmaps, (list, tuple)) and dofmaps:
        return dofmaps[0]
    dofmap = mesh.geometry.dofmap
    if isinstance(dofmap, np.ndarray):
        return dofmap
    tdim = mesh.topology.dim
    index_map = mesh.topology.index_map(tdim)
    return dofmap.array.reshape(index_map.size_local + index_map.num_ghosts, -1)


# ------------------------------------------------------------------ coordinate element

def settle_coordinate_element(mesh) -> None:
    """Give the mesh's UFL coordinate element the point variant FFCx would give it.

    FFCx 0.5 sets the variant of a mesh's Lagrange coordinate element to "equispaced" the
    first time it compiles a form on that mesh (ffcx/analysis.py), in place. That changes the
    repr, hence the hash, of every Argument made afterwards: a form that holds a test function
    made before the first compilation and one made after fails UFL's check ("Found different
    Arguments with same number and part"), but only when FFCx compiles it, i.e. when the JIT
    cache misses. Setting the variant before any form is made keeps every Argument alike.
    Meshes whose coordinate element has a variant already (gmsh meshes, basix elements of
    later versions) are left as they are.
    """
    domain = mesh.ufl_domain()
    element = getattr(domain, "_ufl_coordinate_element", None)
    sub = getattr(element, "_sub_element", None)
    if sub is None or getattr(sub, "_variant", "set") is not None:
        return
    scalar = ufl.FiniteElement(element.family(), element.cell(), element.degree(),
                               element.quadrature_scheme(), variant="equispaced")
    domain._ufl_coordinate_element = ufl.VectorElement(scalar)


# ------------------------------------------------------------------ UFL traversal caches

def release_dispatch_caches():
    """Stop functools.singledispatchmethod from caching bound methods in UFL and FFCx.

    CPython 3.13.0 caches each bound method in a WeakKeyDictionary whose value refers back
    to its key, so no entry is ever dropped (CPython issue gh-127750; the cache came with
    3.13.0 and went in a later 3.13 bugfix release, gh-130008). UFL >= 2025 differentiates
    with DAGTraverser objects whose `process` is such a method, and each traverser keeps the
    expressions it saw: every ufl.derivative, fem.form and fem.Expression then keeps its
    meshes, spaces and Functions alive for ever, and with them the MPI communicators of their
    index maps, until MPI runs out of them (MPICH: 2048 per process). Without the cache
    attribute (older UFL, other Python versions) nothing is done. Called on import.
    """
    import importlib
    import sys
    for name in ("ufl.algorithms.apply_derivatives", "ufl.algorithms.apply_coefficient_split",
                 "ffcx.codegeneration.C.formatter"):
        try:
            importlib.import_module(name)
        except ImportError:
            pass
    for name, module in list(sys.modules.items()):
        if module is None or name.split(".")[0] not in ("ufl", "ffcx"):
            continue
        for cls in list(vars(module).values()):
            if not isinstance(cls, type):
                continue
            for attribute in vars(cls).values():
                if isinstance(attribute, functools.singledispatchmethod) \
                        and getattr(attribute, "_method_cache", None) is not None:
                    attribute._method_cache = None     # as the fixed CPython does


release_dispatch_caches()


# ------------------------------------------------------------------ PETSc garbage

def destroy_petsc_objects(owner, borrowed=()) -> None:
    """Destroy the PETSc objects that `owner` holds in its attributes, directly or in lists,
    tuples and dict values (collective on their communicators; destroying twice does
    nothing), except in the attributes named in `borrowed`: objects that belong to another
    owner, such as a Function's vector."""
    def destroy(value):
        if isinstance(value, PETSc.Object):
            value.destroy()
        elif isinstance(value, (list, tuple)):
            for item in value:
                destroy(item)
        elif isinstance(value, dict):
            for item in value.values():
                destroy(item)

    for name, value in vars(owner).items():
        if name not in borrowed:
            destroy(value)


_LASTING: dict = {}


def _lasting_key(comm) -> tuple:
    """The ranks of `comm` in MPI.COMM_WORLD: one key for every congruent communicator."""
    from mpi4py import MPI
    group, world = comm.Get_group(), MPI.COMM_WORLD.Get_group()
    try:
        return tuple(MPI.Group.Translate_ranks(group, list(range(comm.size)), world))
    finally:
        group.Free()
        world.Free()


def lasting_comm(comm):
    """A communicator congruent to `comm` that lives as long as the process (made once per
    group of ranks; collective the first time), for the PETSc objects a problem holds: they
    become garbage whenever the problem is dropped, and on a communicator that is never
    freed release_petsc_garbage can still destroy them afterwards. `comm` itself for one
    rank, whose objects are destroyed at once."""
    if comm.size == 1:
        return comm
    key = _lasting_key(comm)
    if key not in _LASTING:
        _LASTING[key] = comm.Dup()
    return _LASTING[key]


def ghosted_vector(space, comm) -> PETSc.Vec:
    """A PETSc vector of a space's layout (owned entries, then its index map's ghosts, as
    the space's own vectors) on `comm`, a communicator congruent to the mesh's."""
    index_map, bs = space.dofmap.index_map, space.dofmap.index_map_bs
    ghosts = np.asarray(index_map.ghosts, dtype=PETSc.IntType)
    vector = PETSc.Vec().createGhost(ghosts, size=(index_map.size_local * bs, PETSc.DECIDE),
                                     bsize=bs, comm=comm)
    vector.set(0.0)
    vector.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    return vector


def release_petsc_garbage(spaces) -> None:
    """Destroy the PETSc objects that Python dropped on the communicators of `spaces` and of
    their mesh (collective on them).

    petsc4py does not destroy a garbage-collected object of more than one rank: it puts it
    on its communicator's list and waits for a collective ``PETSc.garbage_cleanup`` there.
    DOLFINx 0.10 and later make each index map its own communicator, and PETSc objects
    assembled on a space (``assemble_vector``, ``create_matrix``) live on that one: once the
    space is freed with garbage still on its communicator, the communicator is never
    released, and MPICH aborts the process after about 2000 of them. DOLFINx 0.5's index
    maps name no communicator: there the mesh's is cleaned (the garbage of its index maps
    only costs memory, and Open MPI does not run out of communicators).
    """
    spaces = list(spaces)
    if not spaces:
        return
    mesh = spaces[0].mesh
    comms = [mesh.comm, _LASTING.get(_lasting_key(mesh.comm)) if mesh.comm.size > 1 else None]
    topology = mesh.topology
    for dim in range(topology.dim + 1):
        try:
            comms.append(getattr(topology.index_map(dim), "comm", None))
        except RuntimeError:           # entities never made (DOLFINx 0.10+ says so)
            pass
    comms += [getattr(space.dofmap.index_map, "comm", None) for space in spaces]
    seen = set()
    for comm in comms:
        if comm is None or comm.size == 1:
            continue
        handle = comm.py2f()
        if handle not in seen:
            seen.add(handle)
            PETSc.garbage_cleanup(comm)


# ------------------------------------------------------------------ point location

def colliding_cells(mesh, points: np.ndarray) -> list[int]:
    """Per point (n x 3), one local cell that contains it, or -1."""
    tdim = mesh.topology.dim
    if hasattr(geometry, "bb_tree"):
        tree = geometry.bb_tree(mesh, tdim)
    else:
        tree = geometry.BoundingBoxTree(mesh, tdim)
    points = np.ascontiguousarray(points, dtype=mesh.geometry.x.dtype)
    candidates = geometry.compute_collisions_points(tree, points) \
        if hasattr(geometry, "compute_collisions_points") \
        else geometry.compute_collisions(tree, points)
    cells = geometry.compute_colliding_cells(mesh, candidates, points)
    return [int(cells.links(i)[0]) if len(cells.links(i)) else -1
            for i in range(len(points))]


# ------------------------------------------------------------------ gmsh

def model_to_mesh(model, comm, rank: int, gdim: int):
    """(mesh, facet tags) of the gmsh model held on `rank`."""
    mesh, _, facet_tags = model_to_tagged_mesh(model, comm, rank, gdim)
    return mesh, facet_tags


def model_to_tagged_mesh(model, comm, rank: int, gdim: int):
    """(mesh, cell tags, facet tags) of the gmsh model held on `rank`."""
    if hasattr(io, "gmsh") and hasattr(io.gmsh, "model_to_mesh"):
        data = io.gmsh.model_to_mesh(model, comm, rank, gdim=gdim)
        return data.mesh, data.cell_tags, data.facet_tags
    from dolfinx.io import gmshio
    return gmshio.model_to_mesh(model, comm, rank, gdim=gdim)


# ------------------------------------------------------------------ output

@functools.lru_cache(maxsize=None)
def xdmf_writes_any_degree() -> bool:
    """Whether XDMFFile writes Functions of another degree than the mesh (P2, DG1): DOLFINx
    0.5 does, later versions refuse. Found by writing a P2 Function of a one-cell mesh into a
    temporary file on this process alone."""
    import tempfile
    from dolfinx import mesh as dmesh
    from mpi4py import MPI
    one_cell = dmesh.create_unit_square(MPI.COMM_SELF, 1, 1)
    function = fem.Function(scalar_space(one_cell, "CG", 2))
    with tempfile.TemporaryDirectory() as folder:
        try:
            with io.XDMFFile(MPI.COMM_SELF, f"{folder}/probe.xdmf", "w") as xdmf:
                xdmf.write_mesh(one_cell)
                xdmf.write_function(function, 0.0)
        except RuntimeError:
            return False
    return True


# ------------------------------------------------------------------ assembly

def _keyword(function, new: str, old: str) -> str:
    """The name a DOLFINx assembly function gives a keyword argument (renamed in 0.10)."""
    try:
        parameters = inspect.signature(function).parameters
    except (TypeError, ValueError):       # a compiled or dispatching function
        return new
    if new in parameters:
        return new
    if old in parameters:
        return old
    # functools.singledispatch: look at the registered implementations
    registry = getattr(function, "registry", {})
    for implementation in registry.values():
        try:
            names = inspect.signature(implementation).parameters
        except (TypeError, ValueError):
            continue
        if new in names:
            return new
        if old in names:
            return old
    return new


_DIAGONAL = _keyword(fem_petsc.assemble_matrix, "diag", "diagonal")
_LIFTING_SCALE = _keyword(fem_petsc.apply_lifting, "alpha", "scale")
_SET_BC_SCALE = _keyword(fem_petsc.set_bc, "alpha", "scale")


def assemble_matrix(A, form, bcs, diagonal: float = 1.0):
    """Assemble a bilinear form into A with Dirichlet rows and columns replaced by `diagonal`
    on the diagonal."""
    fem_petsc.assemble_matrix(A, form, bcs=bcs, **{_DIAGONAL: diagonal})


def apply_lifting(b, forms, bcs, x0, scale: float):
    """b -= scale A (g - x0) for the Dirichlet values g (the lifting of eq. rows)."""
    fem_petsc.apply_lifting(b, forms, bcs=bcs, x0=x0, **{_LIFTING_SCALE: scale})


def set_bc(b, bcs, x0, scale: float):
    """b[dofs] = scale (g - x0)[dofs] on Dirichlet dofs."""
    fem_petsc.set_bc(b, bcs, x0, **{_SET_BC_SCALE: scale})


#: DOLFINx 0.5-0.9 has the *_block functions for a blocked (not nested) system; later versions
#: do the same with the plain functions given lists of forms.
_BLOCK_FUNCTIONS = hasattr(fem_petsc, "assemble_vector_block")


#: create_vector takes the linear form up to DOLFINx 0.9 and its space from 0.10 on.
_VECTOR_OF_SPACE = "L" not in inspect.signature(fem_petsc.create_vector).parameters


def form_vector(form) -> PETSc.Vec:
    """A ghosted vector for the values of a linear form."""
    if _VECTOR_OF_SPACE:
        return fem_petsc.create_vector(form.function_spaces[0])
    return fem_petsc.create_vector(form)


def block_vector(forms) -> PETSc.Vec:
    """A ghosted vector for the stacked unknowns of the linear forms `forms`: on each rank the
    owned values of every block, then the ghosts of every block."""
    if _BLOCK_FUNCTIONS:
        return fem_petsc.create_vector_block(forms)
    spaces = [f.function_spaces[0] for f in forms]
    return fem_petsc.create_vector(spaces)


def block_matrix(forms) -> PETSc.Mat:
    """One (aij) matrix for the blocks of bilinear forms `forms` (a nested list)."""
    if _BLOCK_FUNCTIONS:
        return fem_petsc.create_matrix_block(forms)
    return fem_petsc.create_matrix(forms)


def _block_offsets(spaces):
    """The "_blocks" layout newer DOLFINx reads from a blocked vector: offsets of the owned
    part of every block, then of the ghosts."""
    sizes = [(V.dofmap.index_map.size_local * V.dofmap.index_map_bs,
              V.dofmap.index_map.num_ghosts * V.dofmap.index_map_bs) for V in spaces]
    owned = np.concatenate([[0], np.cumsum([s[0] for s in sizes])])
    ghosts = owned[-1] + np.concatenate([[0], np.cumsum([s[1] for s in sizes])])
    return tuple(int(o) for o in owned), tuple(int(g) for g in ghosts)


def assemble_block_residual(b, F, J, bcs, x, scale: float = -1.0):
    """b = F(x) with the rows of Dirichlet dofs set to scale (g - x) and the lifting of their
    columns, for the stacked unknowns (the block system of the saddle point); x = None
    stands for x = 0."""
    if _BLOCK_FUNCTIONS:
        fem_petsc.assemble_vector_block(b, F, J, bcs=bcs, x0=x, **{_LIFTING_SCALE: scale})
        return
    spaces = [f.function_spaces[0] for f in F]
    blocks = _block_offsets(spaces)
    for vector in (b, x):
        if vector is not None:
            vector.setAttr("_blocks", blocks)
    fem_petsc.assemble_vector(b, F)
    bcs1 = fem.bcs_by_block(fem.extract_function_spaces(J, 1), bcs)
    apply_lifting(b, J, bcs=bcs1, x0=x, scale=scale)
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    bcs0 = fem.bcs_by_block(spaces, bcs)
    set_bc(b, bcs0, x, scale)
    b.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)


def assemble_block_matrix(A, J, bcs, diagonal: float = 1.0):
    """The block Jacobian J into A, Dirichlet rows and columns of every block replaced by
    `diagonal` on the diagonal."""
    if _BLOCK_FUNCTIONS:
        fem_petsc.assemble_matrix_block(A, J, bcs=bcs, **{_DIAGONAL: diagonal})
    else:
        assemble_matrix(A, J, bcs, diagonal)


# ------------------------------------------------------------------ PETSc

def has_hypre() -> bool:
    """Whether PETSc was built with hypre (BoomerAMG)."""
    return bool(PETSc.Sys.hasExternalPackage("hypre"))


def vtk_mesh(space):
    """(topology, cell types, points) of a space's nodes for pyvista.UnstructuredGrid:
    dolfinx.plot.vtk_mesh (0.7 on) or create_vtk_mesh (0.5)."""
    from dolfinx import plot
    make = getattr(plot, "vtk_mesh", None) or plot.create_vtk_mesh
    return make(space)
