"""The Hessian by differences of the gradient: the tests' reference for the exact one
(:func:`retime.physics.timing.objective.hessian_c`), which replaced it in Newton's method."""
import numpy as np


def difference_steps(coords, z):
    """Central-difference steps: 1e-9 s of source time per coefficient (more on long clips, where the
    coefficients' own rounding grows), 1e-9 of the duration. The objective's second derivatives
    change over distances of 1e-8 s (a sample crossing a region's boundary, where the exact
    penalty's curvature starts): a larger step averages across them and the model stops predicting."""
    steps = 1e-9 * np.maximum(1.0, np.abs(z))
    if coords.free_T:
        steps[-1] = 1e-9 * abs(z[-1])
    return steps


def banded_hessian(fun, z, steps, g=None):
    """(ab, col, corner): the Hessian of ``fun`` at z by differences of its gradient with graph
    colouring. ``ab`` is the band of the c-part in the upper form of :func:`scipy.linalg.solveh_banded`
    (band + 1 rows, the band from the spline: :attr:`BandedCoordinates.band`), ``col`` its T column
    (None without T), ``corner`` d2F/dT2. ``steps``: the difference step per coordinate. With ``g``,
    the gradient at z, forward differences (one gradient per colour); without it, central ones (two)."""
    band = fun.coords.band
    colours = 2 * band + 1
    n_c = len(steps) - (1 if fun.coords.free_T else 0)
    offsets = np.arange(-band, band + 1)

    def change(e):
        """dg/de along the step e (forward or central)."""
        return fun(z + e)[1] - g if g is not None else 0.5 * (fun(z + e)[1] - fun(z - e)[1])

    full = np.zeros((2 * band + 1, n_c))  # full[band + j - k, k] = H[j, k], from column k's gradient change
    for r in range(colours):
        cols = np.arange(r, n_c, colours)
        if len(cols) == 0:
            continue
        e = np.zeros(len(z))
        e[cols] = steps[cols]
        dg = change(e)
        rows = cols[None, :] + offsets[:, None]  # (2 band + 1, len(cols)): the rows each column reaches
        inside = (rows >= 0) & (rows < n_c)
        block = np.where(inside, dg[np.clip(rows, 0, n_c - 1)], 0.0) / steps[cols][None, :]
        full[:, cols] = block
    col = corner = None
    if fun.coords.free_T:
        e = np.zeros(len(z))
        e[-1] = steps[-1]
        dg = change(e) / steps[-1]
        col, corner = dg[:n_c], float(dg[-1])
    # upper form: ab[band - off, k] = H[k - off, k], the mean of the entry from column k and from column k - off
    ab = np.zeros((band + 1, n_c))
    ab[band] = full[band]
    for off in range(1, band + 1):
        ab[band - off, off:] = 0.5 * (full[band - off, off:] + full[band + off, :-off])
    return ab, col, corner
