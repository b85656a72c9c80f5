"""Small helpers for the demos (Jupyter or script)."""
import os
import pathlib


def quick() -> bool:
    """True when CONTACTVISCO_QUICK is set: demos then use small sizes (the test suite sets it
    so that every demo runs in seconds)."""
    return bool(os.environ.get("CONTACTVISCO_QUICK"))


def show_images(*paths, scale: float = 1.4):
    """Display PNG files one below the other, inline in a notebook: each at `scale` times its
    print size (the dpi saved in the file; 8 pt text then reads as about 11 pt), at most
    1000 pixels wide, with the file's own pixels (no resampling through a plot). Outside
    IPython the paths are printed."""
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
    PNG at `scale` times its print size, drawn at `dpi` (sharp on any screen). Outside
    IPython nothing is shown."""
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
