"""A quarter of a circular cylinder of tetrahedra (3D), its axis the z axis: x, y >= 0,
x^2 + y^2 <= radius^2, -height <= z <= 0; the 3D twin of axisymmetric_block. Sizes as there:
h_contact within `refine` of the origin (x, y, z) = (0, 0, 0), where an indenter on the axis
touches the top, then h_contact + growth (d - refine) with the distance d, up to h_far.

Boundaries: "xsym" (x = 0) and "ysym" (y = 0), the planes of symmetry; "bottom" (z = -height),
"side" (x^2 + y^2 = radius^2), "top" (z = 0).
"""
import math

from refinement import grow_from_origin


def build(gmsh, radius=10.0, height=10.0, h_contact=0.05, h_far=1.0, refine=0.2, growth=0.3):
    occ = gmsh.model.occ
    volume = occ.addCylinder(0, 0, -height, 0, 0, height, radius, angle=math.pi / 2)
    occ.synchronize()
    eps = 1e-3 * min(radius, height)
    boxes = {"xsym": (-eps, -eps, -height - eps, eps, radius + eps, eps),
             "ysym": (-eps, -eps, -height - eps, radius + eps, eps, eps),
             "bottom": (-eps, -eps, -height - eps, radius + eps, radius + eps, -height + eps),
             "top": (-eps, -eps, -eps, radius + eps, radius + eps, eps)}
    named = set()
    for name, box in boxes.items():
        found = [tag for _, tag in gmsh.model.getEntitiesInBoundingBox(*box, dim=2)]
        named.update(found)
        gmsh.model.setPhysicalName(2, gmsh.model.addPhysicalGroup(2, found), name)
    side = [tag for _, tag in gmsh.model.getEntities(2) if tag not in named]
    gmsh.model.setPhysicalName(2, gmsh.model.addPhysicalGroup(2, side), "side")
    gmsh.model.setPhysicalName(3, gmsh.model.addPhysicalGroup(3, [volume]), "body")
    grow_from_origin(gmsh, h_contact, h_far, refine, growth, "Sqrt(x * x + y * y + z * z)")
    gmsh.model.mesh.generate(3)
