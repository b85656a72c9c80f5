"""A run's PNG figures are drawn once and cropped to their drawn pixels (figures._save,
figures.ink_crop): the crop keeps every drawn pixel with savefig.pad_inches around it, and
frames the picture as savefig's tight box does, to a few pixels (0.1 inch at most)."""
import io

import numpy as np
from matplotlib.figure import Figure
from PIL import Image

from contactvisco.post import figures


def test_ink_crop_keeps_every_drawn_pixel_and_the_pad():
    rng = np.random.default_rng(3)
    image = np.full((60, 90, 4), 255, dtype=np.uint8)
    image[12:40, 20:71, :3] = rng.integers(0, 200, (28, 51, 3))
    image[50, 7] = (0, 0, 0, 255)                       # one stray drawn pixel
    out = figures.ink_crop(image, 3)
    assert out.shape == (51 - 12 + 6, 71 - 7 + 6, 4)
    assert np.array_equal(out[3:3 + 28, 3 + 13:3 + 13 + 51], image[12:40, 20:71])
    assert np.array_equal(out[3 + 38, 3], image[50, 7])
    border = np.concatenate([out[:3].reshape(-1, 4), out[-3:].reshape(-1, 4),
                             out[:, :3].reshape(-1, 4), out[:, -3:].reshape(-1, 4)])
    assert np.all(border == 255)
    # the same on a non-uint8 image (no word view): the same crop
    assert np.array_equal(figures.ink_crop(image.astype(np.int16), 3), out)
    blank = np.full((5, 6, 4), 255, dtype=np.uint8)
    assert np.array_equal(figures.ink_crop(blank, 2), blank)


def _figure():
    fig = Figure(figsize=(3.35, 2.6), layout="constrained")
    ax = fig.subplots()
    ax.plot([0, 1, 2], [0, 1, 4], marker="o", label="a line")
    ax.set_title("a title")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.3), ncol=2, frameon=False)
    return fig


def test_saved_png_frames_the_figure_as_savefig_does():
    """The PNG of _save against savefig's tight box of the same figure at the same dpi: the
    same picture size to 0.1 inch (savefig's box holds the empty space of text and legend
    boxes; the crop only what is drawn), with the pad of background all around."""
    with figures.matplotlib.rc_context(figures.STYLE):
        dpi = 150
        pad = round(figures.matplotlib.rcParams["savefig.pad_inches"] * dpi)
        ours, theirs = io.BytesIO(), io.BytesIO()
        figures._save(_figure(), ours, "png", dpi)
        _figure().savefig(theirs, format="png", dpi=dpi)
    a = np.asarray(Image.open(io.BytesIO(ours.getvalue())).convert("RGBA"))
    b = np.asarray(Image.open(io.BytesIO(theirs.getvalue())).convert("RGBA"))
    assert np.all(np.abs(np.array(a.shape[:2]) - np.array(b.shape[:2])) <= 0.1 * dpi), \
        (a.shape, b.shape)
    drawn = np.any(a != a[0, 0], axis=-1)
    rows, columns = np.flatnonzero(drawn.any(axis=1)), np.flatnonzero(drawn.any(axis=0))
    assert (rows[0], columns[0]) == (pad, pad)
    assert (a.shape[0] - 1 - rows[-1], a.shape[1] - 1 - columns[-1]) == (pad, pad)
    # as much drawn in both: the same picture, not a part of it
    ink_a = np.count_nonzero(drawn)
    ink_b = np.count_nonzero(np.any(b != b[0, 0], axis=-1))
    assert abs(ink_a - ink_b) <= 0.05 * ink_b, (ink_a, ink_b)
