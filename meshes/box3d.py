"""A box [0, lx] x [0, ly] x [0, lz] of tetrahedra (3D).

Boundaries: "left"/"right" (x), "front"/"back" (y), "bottom"/"top" (z). With h_corner the
mesh is refined to h_corner within `refine` of the corner (0, 0, 0), growing to h (an
indenter at the corner of a quarter model); with h_edge, to h_edge within `refine` of the
edge x = 0, z = 0 along y (a cylinder along y at the edge of a half model).
"""
from refinement import refine_near


def build(gmsh, lx=1.0, ly=1.0, lz=0.5, h=0.125, h_corner=None, refine=0.25,
          h_edge=None):
    occ = gmsh.model.occ
    volume = occ.addBox(0, 0, 0, lx, ly, lz)
    occ.synchronize()
    eps = 1e-3 * min(lx, ly, lz)     # OCC pads entity bounding boxes by its tolerance
    faces = {"left": (0, 0), "right": (0, lx), "front": (1, 0), "back": (1, ly),
             "bottom": (2, 0), "top": (2, lz)}
    upper = (lx, ly, lz)
    for name, (axis, value) in faces.items():
        low = [-eps, -eps, -eps]
        high = [u + eps for u in upper]
        low[axis], high[axis] = value - eps, value + eps
        found = gmsh.model.getEntitiesInBoundingBox(*low, *high, dim=2)
        group = gmsh.model.addPhysicalGroup(2, [tag for _, tag in found])
        gmsh.model.setPhysicalName(2, group, name)
    gmsh.model.setPhysicalName(3, gmsh.model.addPhysicalGroup(3, [volume]), "body")
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.option.setNumber("Mesh.MeshSizeMin", h)
    if h_corner is not None:
        gmsh.option.setNumber("Mesh.MeshSizeMin", h_corner)
        corner = gmsh.model.getEntitiesInBoundingBox(-eps, -eps, -eps, eps, eps, eps, dim=0)
        refine_near(gmsh, h_corner, h, refine, 2 * refine + 4 * h,
                    points=[tag for _, tag in corner])
    elif h_edge is not None:
        gmsh.option.setNumber("Mesh.MeshSizeMin", h_edge)
        edge = gmsh.model.getEntitiesInBoundingBox(-eps, -eps, -eps, eps, ly + eps, eps, dim=1)
        refine_near(gmsh, h_edge, h, refine, 2 * refine + 4 * h,
                    curves=[tag for _, tag in edge])
    gmsh.model.mesh.generate(3)
