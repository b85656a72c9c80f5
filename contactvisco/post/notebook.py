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


def show_images(*paths, scale: float = 1.4):
    """Display PNG files one below the other, inline in a notebook, with the file's own pixels
    (no resampling through a plot). Outside IPython the paths are printed.

    Parameters
    ----------
    *paths : path-like
        The image files; a missing one is named and skipped.
    scale : float, optional
        Each image is shown at `scale` times its print size (the dpi saved in the file; 8 pt
        text then reads as about 11 pt), at most 1000 pixels wide.
    """
    try:
        from IPython import get_ipython
        from IPython.display import Image, display
    except ImportError:
        get_ipython = None
    for path in paths:
        path = pathlib.Path(path)
        if not path.exists():
            print(f"(no {path.name})")
            continue
        if get_ipython is None or get_ipython() is None:
            print(path)
            continue
        display(Image(filename=str(path), width=_screen_width(path, scale)))


def show_figure(fig, scale: float = 1.4, dpi: int = 200):
    """Display a matplotlib Figure made without pyplot (contactvisco.post.figures) inline as a
    PNG. Outside IPython nothing is shown.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    scale : float, optional
        Shown at `scale` times its print size, at most 1000 pixels wide.
    dpi : int, optional
        The resolution it is drawn at (sharp on any screen).
    """
    import io
    try:
        from IPython import get_ipython
        from IPython.display import Image, display
    except ImportError:
        return
    if get_ipython() is None:
        return
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi, bbox_inches="tight", pad_inches=0.03)
    from PIL import Image as PILImage
    buffer.seek(0)
    with PILImage.open(buffer) as image:
        width = int(min(1000, round(image.width / dpi * scale * 96)))
    display(Image(data=buffer.getvalue(), format="png", width=width))


def _screen_width(path: pathlib.Path, scale: float) -> int:
    """Pixels on screen for a PNG: its print width (pixels / saved dpi) x scale x 96 px per
    inch, at most 1000."""
    from PIL import Image as PILImage
    with PILImage.open(path) as image:
        dpi = float((image.info.get("dpi") or (96.0, 96.0))[0]) or 96.0
        inches = image.width / dpi
    return int(min(1000, round(inches * scale * 96)))
