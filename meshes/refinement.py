"""Shared by the mesh scripts: a mesh size that grows with the distance from given entities."""


def refine_near(gmsh, size_min, size_max, dist_min, dist_max, points=(), curves=()):
    """Size size_min within dist_min of the points/curves, growing linearly to size_max at
    dist_max; sizes from points, curvature and boundary extension are switched off."""
    field = gmsh.model.mesh.field
    distance = field.add("Distance")
    if points:
        field.setNumbers(distance, "PointsList", list(points))
    if curves:
        field.setNumbers(distance, "CurvesList", list(curves))
    threshold = field.add("Threshold")
    field.setNumber(threshold, "InField", distance)
    field.setNumber(threshold, "SizeMin", size_min)
    field.setNumber(threshold, "SizeMax", size_max)
    field.setNumber(threshold, "DistMin", dist_min)
    field.setNumber(threshold, "DistMax", dist_max)
    field.setAsBackgroundMesh(threshold)
    for option in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints", "MeshSizeFromCurvature"):
        gmsh.option.setNumber(f"Mesh.{option}", 0)


def grow_from_origin(gmsh, h_contact, h_far, refine, growth, distance):
    """Size h_contact within `refine` of the origin, then h_contact + growth (d - refine) with
    the distance d (the gmsh expression `distance`), up to h_far; sizes from points, curvature
    and boundary extension are switched off."""
    field = gmsh.model.mesh.field
    size = field.add("MathEval")
    field.setString(size, "F", f"Min({h_far!r}, {h_contact!r} + {growth!r} * "
                               f"Max(0, {distance} - {refine!r}))")
    field.setAsBackgroundMesh(size)
    for option in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints", "MeshSizeFromCurvature"):
        gmsh.option.setNumber(f"Mesh.{option}", 0)
