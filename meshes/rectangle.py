"""A rectangle [0, length] x [0, height] of triangles (2D), finer near the bottom.

Boundaries: "left", "right", "bottom", "top".
"""
from refinement import refine_near


def build(gmsh, length=4.0, height=1.0, h=0.1, h_bottom=None):
    geo = gmsh.model.geo
    corners = [geo.addPoint(x, y, 0.0) for x, y in
               ((0, 0), (length, 0), (length, height), (0, height))]
    bottom, right, top, left = (geo.addLine(corners[i], corners[(i + 1) % 4]) for i in range(4))
    surface = geo.addPlaneSurface([geo.addCurveLoop([bottom, right, top, left])])
    geo.synchronize()
    for dim, tags, name in ((1, [left], "left"), (1, [right], "right"), (1, [bottom], "bottom"),
                            (1, [top], "top"), (2, [surface], "body")):
        gmsh.model.setPhysicalName(dim, gmsh.model.addPhysicalGroup(dim, tags), name)
    refine_near(gmsh, h_bottom or h, h, 0.1 * height, 0.5 * height, curves=[bottom])
    gmsh.model.mesh.generate(2)
