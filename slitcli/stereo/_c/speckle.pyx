"""Speckle removal of the disparity filters (slitcli.stereo.filters, slitcli.stereo.sgm).

- :func:`speckle_finish`: regions of at most ``max_size`` pixels (cv2.filterSpeckles'
  regions on 1/16 px) removed, then the NaN of every invalid pixel;
- :func:`speckle_small`: the valid pixels it would remove, marked only (the SGM
  bracket test asks this before its fills).

Both release the GIL and find the regions with one union-find raster pass.
"""

from libc.math cimport NAN
from libc.stdint cimport int16_t, int32_t, int64_t, uint8_t
from libc.stdlib cimport free, llabs, malloc


cdef inline int32_t _root(int32_t* parent, int32_t i) noexcept nogil:
    """Root of i's set (path halving; every link points to an earlier pixel)."""
    cdef int32_t p
    while parent[i] != i:
        p = parent[i]
        parent[i] = parent[p]
        i = p
    return i


cdef void _speckle_union(const float[:, ::1] disp, const uint8_t[:, ::1] reason,
                         int64_t max_diff_16, int32_t* fixed, int32_t* parent,
                         int32_t* size) noexcept nogil:
    """The union-find pass of :func:`speckle_finish` (reads ``disp`` and ``reason``)."""
    cdef Py_ssize_t height = disp.shape[0], width = disp.shape[1], y, x, i
    cdef int32_t run, f, root, up, lo, hi
    for y in range(height):
        run = -1     # root of the set of pixel x - 1, -1 when it is invalid
        for x in range(width):
            i = y * width + x
            if reason[y, x] != 0:
                run = -1
                continue
            # numba's np.int16(float32): the conversion to 32 bits, then its low 16 bits
            f = <int16_t> (<int32_t> (disp[y, x] * <float> 16.0))
            fixed[i] = f
            if run >= 0 and llabs(<int64_t> f - fixed[i - 1]) <= max_diff_16:
                parent[i] = run
                size[run] += 1
                root = run
            else:
                parent[i] = <int32_t> i
                size[i] = 1
                root = <int32_t> i
            if y > 0 and reason[y - 1, x] == 0 and \
                    llabs(<int64_t> f - fixed[i - width]) <= max_diff_16:
                up = _root(parent, <int32_t> (i - width))
                if up != root:
                    lo = up if up < root else root
                    hi = up if up > root else root
                    parent[hi] = lo
                    size[lo] += size[hi]
                    root = lo
            run = root


cdef inline bint _small_root(int32_t* parent, int32_t* size, Py_ssize_t i,
                             int64_t max_size) noexcept nogil:
    """Whether pixel ``i``'s region holds at most ``max_size`` pixels; flattens
    ``parent[i]`` to the region's root (``parent[i] < i`` is already flattened)."""
    cdef int32_t r = parent[parent[i]]
    parent[i] = r
    return size[r] <= max_size


cdef void _speckle_regions(float[:, ::1] disp, uint8_t[:, ::1] reason, int64_t max_size,
                           int64_t max_diff_16, int64_t speckle_code, int32_t* fixed,
                           int32_t* parent, int32_t* size) noexcept nogil:
    """The union-find pass and the marking pass of :func:`speckle_finish`."""
    cdef Py_ssize_t height = disp.shape[0], width = disp.shape[1], y, x, i
    cdef float nan32 = NAN
    _speckle_union(disp, reason, max_diff_16, fixed, parent, size)
    for y in range(height):
        for x in range(width):
            i = y * width + x
            if reason[y, x] == 0:
                if _small_root(parent, size, i, max_size):
                    reason[y, x] = <uint8_t> speckle_code
                    disp[y, x] = nan32
            else:
                disp[y, x] = nan32


def speckle_finish(float[:, ::1] disp, uint8_t[:, ::1] reason, int64_t max_size,
                   int64_t max_diff_16, int64_t speckle_code) -> None:
    """Speckle removal, then NaN for every invalid pixel, in place.

    The regions are those of ``cv2.filterSpeckles`` on the disparities in 1/16 px
    (``trunc(16 d)``): 4-connected valid pixels whose neighbours differ by at most
    ``max_diff_16``. Valid pixels of regions of at most ``max_size`` pixels get
    ``speckle_code`` (``max_size`` 0: no speckle removal). The regions are the
    connected components of a union-find built in one raster pass (a pixel joins the
    run on its left, runs join the row above; every set is rooted at its first pixel,
    so a second raster pass reads each pixel's root in O(1)): O(pixels), and
    independent of the order of the pass.

    Parameters
    ----------
    disp : ndarray, shape (H, W), float32
        Disparity, px; modified in place.
    reason : ndarray, shape (H, W), uint8
        Invalid reason (0 valid); modified in place.
    max_size, max_diff_16, speckle_code : int
    """
    cdef Py_ssize_t height = disp.shape[0], width = disp.shape[1], y, x
    cdef Py_ssize_t npx = height * width
    cdef float nan32 = NAN
    if reason.shape[0] != height or reason.shape[1] != width:
        raise ValueError("speckle_finish: disp and reason (H, W)")
    if npx >= 2 ** 31:
        raise ValueError("speckle_finish: at most 2**31 - 1 pixels")
    if max_size <= 0:
        with nogil:
            for y in range(height):
                for x in range(width):
                    if reason[y, x] != 0:
                        disp[y, x] = nan32
        return
    cdef int32_t* buf = <int32_t*> malloc(3 * (npx + 1) * sizeof(int32_t))
    if buf == NULL:
        raise MemoryError()
    with nogil:
        _speckle_regions(disp, reason, max_size, max_diff_16, speckle_code, buf,
                         buf + npx + 1, buf + 2 * (npx + 1))
    free(buf)


def speckle_small(const float[:, ::1] disp, const uint8_t[:, ::1] reason, int64_t max_size,
                  int64_t max_diff_16, uint8_t[:, ::1] small) -> None:
    """The valid pixels :func:`speckle_finish` would mark, without marking them.

    ``small`` (H, W) bool (as uint8) is set to 1 at valid pixels (``reason`` 0) of
    regions of at most ``max_size`` pixels, 0 elsewhere; the regions are those of
    :func:`speckle_finish` (the same union-find), ``disp`` and ``reason`` are only
    read (no copies, no NaN pass: the SGM bracket test asks this before its fills).
    ``max_size`` must be > 0.
    """
    cdef Py_ssize_t height = disp.shape[0], width = disp.shape[1], y, x, i
    cdef Py_ssize_t npx = height * width
    if (reason.shape[0] != height or reason.shape[1] != width or small.shape[0] != height
            or small.shape[1] != width):
        raise ValueError("speckle_small: disp, reason and small (H, W)")
    if npx >= 2 ** 31:
        raise ValueError("speckle_small: at most 2**31 - 1 pixels")
    if max_size <= 0:
        raise ValueError("speckle_small: max_size must be > 0")
    cdef int32_t* buf = <int32_t*> malloc(3 * (npx + 1) * sizeof(int32_t))
    if buf == NULL:
        raise MemoryError()
    cdef int32_t* parent = buf + npx + 1
    cdef int32_t* size = buf + 2 * (npx + 1)
    with nogil:
        _speckle_union(disp, reason, max_diff_16, buf, parent, size)
        for y in range(height):
            for x in range(width):
                i = y * width + x
                if reason[y, x] == 0:
                    small[y, x] = _small_root(parent, size, i, max_size)
                else:
                    small[y, x] = 0
    free(buf)
