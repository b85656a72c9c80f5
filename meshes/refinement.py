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
