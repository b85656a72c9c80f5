"""A quarter of a cylinder's cross-section touching the foundation y = 0 at the origin (2D).

Centre (0, R); boundaries: "contact" (the arc from (0, 0) to (R, R)), "top" (y = R),
"axis" (x = 0, the symmetry line). The mesh is refined to h_contact within `refine` of the
contact point and grows to h_far away from it.
"""
from refinement import refine_near


def build(gmsh, radius=1.0, h_contact=0.005, h_far=0.1, refine=0.25):
    geo = gmsh.model.geo
    bottom = geo.addPoint(0.0, 0.0, 0.0)
    centre = geo.addPoint(0.0, radius, 0.0)
    right = geo.addPoint(radius, radius, 0.0)
    arc = geo.addCircleArc(bottom, centre, right)
    top = geo.addLine(right, centre)
    axis = geo.addLine(centre, bottom)
    surface = geo.addPlaneSurface([geo.addCurveLoop([arc, top, axis])])
    geo.synchronize()
    for dim, tags, name in ((1, [arc], "contact"), (1, [top], "top"), (1, [axis], "axis"),
                            (2, [surface], "body")):
        gmsh.model.setPhysicalName(dim, gmsh.model.addPhysicalGroup(dim, tags), name)
    refine_near(gmsh, h_contact, h_far, refine, 2 * refine + 10 * h_far, points=[bottom])
    gmsh.model.mesh.generate(2)
