"""Block correlations of the support tests, callable from Python (tests, benches).

The kernels themselves are the inline functions of ``zncc.pxd``, compiled into
slitcli.stereo._c.boundary, which uses them; this module only wraps them.
"""


def blocks(const float[:, ::1] gl, const float[:, ::1] gr, const Py_ssize_t[::1] yc,
           const Py_ssize_t[::1] xc, const float[::1] d, Py_ssize_t n, Py_ssize_t rx,
           Py_ssize_t ry, float[::1] out, float nv=0.0, float nvf=0.0,
           float nfr=1.0):
    """``out[i]`` = the zero-mean normalised correlation of the (2 rx + 1) x (2 ry + 1)
    left block centred at (``xc[i]``, ``yc[i]``) (clipped to the image) with the right
    image at ``xc[i] - d[i]`` (linear in x), i < n; 0 where a block is flat or has
    fewer than 2 samples. Blocks inside the image eight at a time.

    Parameters
    ----------
    gl, gr : (H, W) float32, C order
        Grey left and right images.
    yc, xc : (>= n,) intp
        Block centres (px); any value (blocks are clipped to the image).
    d : (>= n,) float32
        Disparities (px, subpixel, any sign).
    n, rx, ry : int
        Number of blocks, half width and half height of a block (px).
    out : (>= n,) float32
        The correlations, in [-1, 1] up to rounding.
    nv, nvf : float
        Noise model (``finish`` of zncc.pxd): noise variance per sample (DN^2) and
        ``nv`` times the variance factor of a block sum; 0: plain correlations.
    nfr : float
        Share of the noise energy taken off (1: all of it).
    """
    _check(gl, gr, yc.shape[0], xc.shape[0], d.shape[0], n, rx, ry, out.shape[0])
    with nogil:
        zncc_blocks(&gl[0, 0], &gr[0, 0], gl.shape[0], gl.shape[1], &yc[0], &xc[0], &d[0],
                    n, rx, ry, &out[0], nv, nvf, nfr)


def blocks_one_at_a_time(const float[:, ::1] gl, const float[:, ::1] gr,
                         const Py_ssize_t[::1] yc, const Py_ssize_t[::1] xc,
                         const float[::1] d, Py_ssize_t n, Py_ssize_t rx, Py_ssize_t ry,
                         float[::1] out, float nv=0.0, float nvf=0.0,
           float nfr=1.0):
    """As :func:`blocks`, every block by the scalar code (the reference of the
    eight-lane one)."""
    _check(gl, gr, yc.shape[0], xc.shape[0], d.shape[0], n, rx, ry, out.shape[0])
    cdef Py_ssize_t i
    with nogil:
        for i in range(n):
            out[i] = zncc_block(&gl[0, 0], &gr[0, 0], gl.shape[0], gl.shape[1], yc[i],
                                xc[i], d[i], rx, ry, nv, nvf, nfr)


cdef _check(const float[:, ::1] gl, const float[:, ::1] gr, Py_ssize_t ny, Py_ssize_t nx,
            Py_ssize_t nd, Py_ssize_t n, Py_ssize_t rx, Py_ssize_t ry, Py_ssize_t nout):
    if gr.shape[0] != gl.shape[0] or gr.shape[1] != gl.shape[1] or gl.shape[1] < 2:
        raise ValueError("gl and gr must have one shape, at least 2 columns")
    if not (0 <= n <= min(ny, nx, nd, nout)) or rx < 0 or ry < 0:
        raise ValueError("n must be at most the length of yc, xc, d and out; rx, ry >= 0")
