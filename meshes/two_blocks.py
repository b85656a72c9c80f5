"""Two rectangles of triangles (2D) that touch along y = 0 without sharing a node: the slave
block [0, length] x [0, height] above the master block [0, length] x [-height, 0].

Each block keeps its own nodes on the interface, spaced by its own size: round(length /
h_slave) slave segments against round(length / h_master) master segments, so the two traces
do not match unless the sizes give the same count; the interface nodes are placed at
exactly x = j length / n (gmsh places them to about 1e-12), so equal counts give nodes at the
same places to the last digit.

Boundaries: "slave" (the slave block's bottom), "master" (the master block's top), "top"
(the slave block's top), "bottom" (the master block's bottom), "slave_sides" and
"master_sides" (each block's left and right; with split_sides = 1 "slave_left",
"slave_right", "master_left" and "master_right" instead). Bodies: "slave_body", "master_body".
"""


def build(gmsh, length=1.0, height=0.5, h_slave=0.077, h_master=0.1, depth=None,
          split_sides=0):
    """The two blocks; `depth` is the master block's height (default: `height`); with
    split_sides = 1 each block's sides are two boundaries, <name>_left and <name>_right,
    instead of <name>_sides."""
    depth = height if depth is None else depth
    # Points at the same place stay two points: each block owns its interface nodes.
    gmsh.option.setNumber("Geometry.AutoCoherence", 0)
    geo = gmsh.model.geo
    groups, interfaces = {}, []
    for name, y0, y1, h in (("slave", 0.0, height, h_slave),
                            ("master", -depth, 0.0, h_master)):
        corners = [geo.addPoint(x, y, 0.0, h) for x, y in
                   ((0, y0), (length, y0), (length, y1), (0, y1))]
        bottom, right, top, left = (geo.addLine(corners[i], corners[(i + 1) % 4])
                                    for i in range(4))
        surface = geo.addPlaneSurface([geo.addCurveLoop([bottom, right, top, left])])
        interface = bottom if name == "slave" else top
        outer = top if name == "slave" else bottom
        geo.synchronize()
        cells = max(1, round(length / h))
        gmsh.model.mesh.setTransfiniteCurve(interface, cells + 1)
        interfaces.append((interface, cells))
        groups[name] = [interface]
        groups["top" if name == "slave" else "bottom"] = [outer]
        if split_sides:
            groups[f"{name}_left"], groups[f"{name}_right"] = [left], [right]
        else:
            groups[f"{name}_sides"] = [left, right]
        groups[f"{name}_body"] = surface
    geo.synchronize()
    for name, tags in groups.items():
        dim = 2 if name.endswith("_body") else 1
        tags = [tags] if dim == 2 else tags
        gmsh.model.setPhysicalName(dim, gmsh.model.addPhysicalGroup(dim, tags), name)
    gmsh.model.mesh.generate(2)
    for curve, cells in interfaces:
        tags, coords, params = gmsh.model.mesh.getNodes(1, curve)
        for tag, xyz, u in zip(tags, coords.reshape(-1, 3), params):
            x = round(xyz[0] * cells / length) * length / cells
            gmsh.model.mesh.setNode(tag, [x, 0.0, 0.0], [u])
