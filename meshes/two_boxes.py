"""Two boxes of tetrahedra (3D) that touch along z = 0 without sharing a node: the slave box
[0, lx] x [0, ly] x [0, height] above the master box [0, lx] x [0, ly] x [-depth, 0].

Each box is meshed with its own size (h_slave, h_master) and keeps its own nodes, so the two
triangulations of the interface do not match (unstructured triangles of two sizes).

Boundaries: "slave" (the slave box's bottom), "master" (the master box's top), "top" (the
slave box's top), "bottom" (the master box's bottom), "slave_x" and "master_x" (each box's
faces x = 0 and x = lx), "slave_y" and "master_y" (y = 0 and y = ly). Bodies: "slave_body",
"master_body".
"""


def build(gmsh, lx=1.0, ly=1.0, height=0.5, depth=0.5, h_slave=0.25, h_master=0.34):
    occ = gmsh.model.occ
    # No fragment: the two volumes stay apart and each meshes its own interface face.
    boxes = {"slave": occ.addBox(0, 0, 0, lx, ly, height),
             "master": occ.addBox(0, 0, -depth, lx, ly, depth)}
    occ.synchronize()
    groups = {}
    for name, volume in boxes.items():
        faces = [tag for _, tag in gmsh.model.getBoundary([(3, volume)], oriented=False)]
        for face in faces:
            x, y, z = occ.getCenterOfMass(2, face)
            if abs(z) < 1e-9 * depth:
                label = name
            elif z > 0.0 and abs(z - height) < 1e-9 * height:
                label = "top"
            elif z < 0.0 and abs(z + depth) < 1e-9 * depth:
                label = "bottom"
            elif abs(x) < 1e-9 * lx or abs(x - lx) < 1e-9 * lx:
                label = f"{name}_x"
            else:
                label = f"{name}_y"
            groups.setdefault(label, []).append(face)
        points = gmsh.model.getBoundary([(3, volume)], oriented=False, recursive=True)
        gmsh.model.mesh.setSize(points, h_slave if name == "slave" else h_master)
    for name, faces in groups.items():
        gmsh.model.setPhysicalName(2, gmsh.model.addPhysicalGroup(2, faces), name)
    for name, volume in boxes.items():
        gmsh.model.setPhysicalName(3, gmsh.model.addPhysicalGroup(3, [volume]),
                                   f"{name}_body")
    gmsh.model.mesh.generate(3)
