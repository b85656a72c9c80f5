"""A block of revolution about the z axis (material.model = "axisymmetric"), meshed in its
meridian half-plane: the rectangle 0 <= r <= radius, -height <= z <= 0 of triangles, graded
towards the origin (r, z) = (0, 0), where an indenter on the axis touches the top: size h_contact
within `refine` of it, then growing in proportion to the distance d beyond it,
h_contact + growth (d - refine), up to h_far. Sizes proportional to the distance keep a fixed
number of elements across each decade of distance, where the contact's stress field decays,
for a number of cells that grows only with the logarithm of the block's size.

Boundaries: "axis" (r = 0), "bottom" (z = -height), "side" (r = radius), "top" (z = 0).
"""
from refinement import grow_from_origin


def build(gmsh, radius=10.0, height=10.0, h_contact=0.01, h_far=1.0, refine=0.2, growth=0.1):
    geo = gmsh.model.geo
    corners = [geo.addPoint(r, z, 0.0) for r, z in
               ((0.0, 0.0), (0.0, -height), (radius, -height), (radius, 0.0))]
    axis, bottom, side, top = (geo.addLine(corners[i], corners[(i + 1) % 4]) for i in range(4))
    surface = geo.addPlaneSurface([geo.addCurveLoop([axis, bottom, side, top])])
    geo.synchronize()
    for dim, tags, name in ((1, [axis], "axis"), (1, [bottom], "bottom"), (1, [side], "side"),
                            (1, [top], "top"), (2, [surface], "body")):
        gmsh.model.setPhysicalName(dim, gmsh.model.addPhysicalGroup(dim, tags), name)
    grow_from_origin(gmsh, h_contact, h_far, refine, growth, "Sqrt(x * x + y * y)")
    gmsh.model.mesh.generate(2)
