"""Small helpers for the demos (Jupyter or script)."""
import os
import pathlib


def quick() -> bool:
    """True when CONTACTVISCO_QUICK is set: demos then use small sizes (the test suite sets it
    so that every demo runs in seconds)."""
    return bool(os.environ.get("CONTACTVISCO_QUICK"))


def show_images(*paths, width=9.0):
    """Display PNG files one below the other (inline in a notebook)."""
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
