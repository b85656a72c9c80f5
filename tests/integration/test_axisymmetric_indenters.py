

def test_plane_strain_die_and_wedge_touch_where_they_reach():
    """In plane strain the same keys give a flat die and a wedge about the vertical line
    through their point: symmetric about it (the nodes in contact mirror each other), the die
    pressing exactly the nodes under its face, the wedge fewer than the die."""
    found = {}
    for shape, extra in (("punch", {"radius": 0.25}), ("cone", {"angle": 80.0})):
        raw = {"name": "die", "geometry": {"lower": [0.0, 0.0], "upper": [2.0, 1.0],
                                           "cells": [32, 16]},
               "material": {"model": "plane_strain", "E": E, "nu": NU},
               "dirichlet": [{"boundary": "bottom", "components": "all"}],
               "contact": {"boundary": "top", "g": 0.0, "mu": 0.0},
               "obstacle": {"shape": shape, "point": [1.0, 1.0],
                            "displacement": [0.0, "-0.01 * t"], **extra},
               "time": {"T": 1.0, "steps": 1}, "output": {"probes": []}}
        result = simulate(scene_module.resolve(raw), comm=COMM, progress=False,
                          keep_tables=True)
        table = result.tables[-1]
        x = table["x"][table["status"] > 0][:, 0]
        assert np.allclose(np.sort(x - 1.0), np.sort(1.0 - x), atol=1e-12)
        assert result.steps[-1]["obstacle"]["force"][1] < 0        # pushes the body down
        found[shape] = x
    assert np.allclose(np.sort(found["punch"]), np.linspace(0.75, 1.25, 9))
    assert 0 < found["cone"].size < found["punch"].size
