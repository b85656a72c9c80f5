"""The docs' shift-table example (docs/scenes.md: its TOML block with shift = "table" and
the points in its comment) as a small scene file, for the tests of every route."""
import pathlib
import re

DOCS = pathlib.Path(__file__).resolve().parents[1] / "docs" / "scenes.md"
POINTS = ([40.0, 50.0, 60.0], [4.19, 0.0, -2.83])

#: The rest of a small scene around the docs' [viscoelastic] table.
REST = """name = "shift_table"
[geometry]
lower = [0.0, 0.0]
upper = [2.0, 1.0]
cells = [4, 2]
[material]
model = "plane_strain"
[[dirichlet]]
boundary = "left"
components = [0]
[[traction]]
boundary = "top"
value = [0.0, -1.0]
[contact]
boundary = "bottom"
stiffness = 100.0
g = 0.03
[time]
T = 1.0
steps = 2
[output]
probes = []
"""


def docs_example() -> str:
    """The docs' TOML block with shift = "table" and its shift_file."""
    blocks = re.findall(r"```toml\n(.*?)```", DOCS.read_text(), re.S)
    found = [b for b in blocks if 'shift = "table"' in b and "shift_file" in b]
    if len(found) != 1:
        raise AssertionError(f"docs/scenes.md has {len(found)} shift-table examples, not 1")
    return found[0]


def write_scene(folder: pathlib.Path) -> pathlib.Path:
    """The example's scene.toml and its shift.csv written in `folder`; the scene's path."""
    rows = "".join(f"{T},{L}\n" for T, L in zip(*POINTS))
    (folder / "shift.csv").write_text("T (C),log10 aT\n" + rows)
    path = folder / "scene.toml"
    path.write_text(REST + docs_example())
    return path
