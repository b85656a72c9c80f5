"""Two half cylinders' cross-sections (2D) touching at the origin without sharing a node: the
lower half of a disk of radius r_upper (centre (0, r_upper), the slave body) resting on the
upper half of a disk of radius r_lower (centre (0, -r_lower), the master body).

Boundaries: "contact" (the upper body's arc within `angle` degrees of its lowest point, the
slave side), "arc" (the rest of its half circle), "top" (y = r_upper, its diameter),
"lower_contact" (the lower body's arc within `angle` degrees of its highest point, the master
side), "lower_arc" (the rest of it) and "bottom" (y = -r_lower, its diameter). Bodies:
"upper" and "lower". Both are refined to h_contact within `refine` of the origin and grow to
h_far away from it.
"""
import math

from refinement import refine_near


def _half_disk(gmsh, radius, side, angle):
    """The half disk of centre (0, side * radius) on the side of the origin (side = 1: the
    lower half of the upper disk; side = -1: the upper half of the lower disk). Returns its
    surface, its arc near the origin, the rest of its arc, its diameter and the point at the
    origin."""
    geo = gmsh.model.geo
    s, c = math.sin(math.radians(angle)), math.cos(math.radians(angle))
    y = side * radius
    centre = geo.addPoint(0.0, y, 0.0)
    touching = geo.addPoint(0.0, 0.0, 0.0)
    left, right = geo.addPoint(-radius, y, 0.0), geo.addPoint(radius, y, 0.0)
    near_left = geo.addPoint(-radius * s, side * radius * (1 - c), 0.0)
    near_right = geo.addPoint(radius * s, side * radius * (1 - c), 0.0)
    near = [geo.addCircleArc(near_left, centre, touching),
            geo.addCircleArc(touching, centre, near_right)]
    far = [geo.addCircleArc(left, centre, near_left),
           geo.addCircleArc(near_right, centre, right)]
    diameter = geo.addLine(right, left)
    loop = [far[0], *near, far[1], diameter]
    surface = geo.addPlaneSurface([geo.addCurveLoop(loop)])
    return surface, near, far, diameter, touching


def build(gmsh, r_upper=1.0, r_lower=2.0, angle=25.0, h_contact=0.005, h_far=0.2,
          refine=0.2):
    gmsh.option.setNumber("Geometry.AutoCoherence", 0)     # each body keeps its own nodes
    upper, contact, arc, top, first = _half_disk(gmsh, r_upper, 1, angle)
    lower, lower_contact, lower_arc, bottom, second = _half_disk(gmsh, r_lower, -1, angle)
    gmsh.model.geo.synchronize()
    for dim, tags, name in ((1, contact, "contact"), (1, arc, "arc"), (1, [top], "top"),
                            (1, lower_contact, "lower_contact"), (1, lower_arc, "lower_arc"),
                            (1, [bottom], "bottom"), (2, [upper], "upper"),
                            (2, [lower], "lower")):
        gmsh.model.setPhysicalName(dim, gmsh.model.addPhysicalGroup(dim, tags), name)
    refine_near(gmsh, h_contact, h_far, refine, 2 * refine + 10 * h_far,
                points=[first, second])
    gmsh.model.mesh.generate(2)
