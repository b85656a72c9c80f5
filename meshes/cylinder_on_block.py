"""The lower half of a cylinder's cross-section (centre (0, R)) resting on a block
[-width, width] x [-depth, 0] (2D): the two bodies touch at the origin and share no node.

Boundaries: "contact" (the cylinder's arc within `angle` degrees of its lowest point, the slave
side), "arc" (the rest of the half circle), "top" (y = R, the diameter), "block_top" (y = 0,
the master side), "bottom" (y = -depth) and "block_sides" (x = -width and x = width). Bodies:
"cylinder" and "block". Both are refined to h_contact within `refine` of the origin and grow
to h_far away from it.
"""
import math

from refinement import refine_near


def build(gmsh, radius=1.0, width=2.0, depth=2.0, angle=25.0, h_contact=0.005, h_far=0.2,
          refine=0.2):
    gmsh.option.setNumber("Geometry.AutoCoherence", 0)     # each body keeps its own nodes
    geo = gmsh.model.geo
    s, c = math.sin(math.radians(angle)), math.cos(math.radians(angle))
    centre = geo.addPoint(0.0, radius, 0.0)
    lowest = geo.addPoint(0.0, 0.0, 0.0)
    left, right = geo.addPoint(-radius, radius, 0.0), geo.addPoint(radius, radius, 0.0)
    near_left = geo.addPoint(-radius * s, radius * (1 - c), 0.0)
    near_right = geo.addPoint(radius * s, radius * (1 - c), 0.0)
    contact = [geo.addCircleArc(near_left, centre, lowest),
               geo.addCircleArc(lowest, centre, near_right)]
    arc = [geo.addCircleArc(left, centre, near_left),
           geo.addCircleArc(near_right, centre, right)]
    top = geo.addLine(right, left)
    cylinder = geo.addPlaneSurface([geo.addCurveLoop([arc[0], *contact, arc[1], top])])
    origin = geo.addPoint(0.0, 0.0, 0.0)
    corners = [geo.addPoint(x, y, 0.0) for x, y in
               ((-width, -depth), (width, -depth), (width, 0.0), (-width, 0.0))]
    bottom = geo.addLine(corners[0], corners[1])
    right_side = geo.addLine(corners[1], corners[2])
    block_top = [geo.addLine(corners[2], origin), geo.addLine(origin, corners[3])]
    left_side = geo.addLine(corners[3], corners[0])
    block = geo.addPlaneSurface([geo.addCurveLoop([bottom, right_side, *block_top,
                                                   left_side])])
    geo.synchronize()
    for dim, tags, name in ((1, contact, "contact"), (1, arc, "arc"), (1, [top], "top"),
                            (1, block_top, "block_top"), (1, [bottom], "bottom"),
                            (1, [left_side, right_side], "block_sides"),
                            (2, [cylinder], "cylinder"), (2, [block], "block")):
        gmsh.model.setPhysicalName(dim, gmsh.model.addPhysicalGroup(dim, tags), name)
    refine_near(gmsh, h_contact, h_far, refine, 2 * refine + 10 * h_far,
                points=[lowest, origin])
    gmsh.model.mesh.generate(2)
