"""Small helpers for the demos (Jupyter or script)."""
import os
import pathlib


def quick() -> bool:
    """Whether the demos should use small sizes.

    Returns
    -------
    bool
        True when the environment variable ``CONTACTVISCO_QUICK`` is set (the test suite sets
        it so that every demo runs in seconds).
    """
    return bool(os.environ.get("CONTACTVISCO_QUICK"))


def show_images(*paths, width=9.0):
    """Display PNG files one below the other (inline in a notebook, in a window otherwise).

    Parameters
    ----------
    *paths : path-like
        The image files; a missing one is named and skipped.
    width : float, optional
        The width of each image in inches.
    """
    import matplotlib.pyplot as plt
    for path in paths:
        path = pathlib.Path(path)
        if not path.exists():
            print(f"(no {path.name})")
            continue
        image = plt.imread(path)
        fig, ax = plt.subplots(figsize=(width, width * image.shape[0] / image.shape[1]))
        ax.imshow(image)
        ax.axis("off")
        plt.show()
