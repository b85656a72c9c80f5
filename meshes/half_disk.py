"""The lower half of a cylinder's cross-section touching the foundation y = 0 at the origin (2D).

Centre (0, R); boundaries: "contact" (the lower half circle, two arcs meeting at (0, 0)) and
"top" (y = R, the diameter). The mesh is refined to h_contact within `refine` of the contact
point and grows to h_far away from it. For loads without symmetry about x = 0 (a tangential
pull), where the quarter section of quarter_disk.py does not apply.
"""
from refinement import refine_near


def build(gmsh, radius=1.0, h_contact=0.005, h_far=0.1, refine=0.25):
    geo = gmsh.model.geo
    bottom = geo.addPoint(0.0, 0.0, 0.0)
    centre = geo.addPoint(0.0, radius, 0.0)
    left = geo.addPoint(-radius, radius, 0.0)
    right = geo.addPoint(radius, radius, 0.0)
    arcs = [geo.addCircleArc(left, centre, bottom), geo.addCircleArc(bottom, centre, right)]
    top = geo.addLine(right, left)
    surface = geo.addPlaneSurface([geo.addCurveLoop(arcs + [top])])
    geo.synchronize()
    for dim, tags, name in ((1, arcs, "contact"), (1, [top], "top"), (2, [surface], "body")):
        gmsh.model.setPhysicalName(dim, gmsh.model.addPhysicalGroup(dim, tags), name)
    refine_near(gmsh, h_contact, h_far, refine, 2 * refine + 10 * h_far, points=[bottom])
    gmsh.model.mesh.generate(2)
