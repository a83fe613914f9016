"""Compiled kernel of :mod:`slitcli.laser.geometry`: the ray/laser-plane intersection of
one frame's stripe rows (DESIGN §4, replacing the paper's Eqs. 5-7). Releases the GIL; the
arithmetic is that of the expressions as written (libm's ``hypot`` and ``atan2``), the
same bits as the numba kernel it replaces.
"""

from libc.math cimport atan2, fabs, hypot, isfinite, isinf, NAN, INFINITY
from libc.stdint cimport uint8_t

#: math.degrees: x * (180 / pi), the quotient rounded once
cdef double _DEG_PER_RAD = 180.0 / 3.141592653589793


def triangulate_columns(const double[::1] v_px, const double[::1] ray_x,
                        const double[::1] ray_y, const double[::1] plane,
                        const double[:, :] sensor_from_cam, double min_range_m,
                        double max_range_m, double[:, ::1] out,
                        uint8_t[::1] in_band) -> None:
    """Sensor-frame points of one frame's stripe rows, column by column
    (:func:`~slitcli.laser.geometry.triangulate_stripe`'s arithmetic).

    Parameters
    ----------
    v_px : ndarray, shape (W,), float64
        Stripe row of every column, px (NaN none).
    ray_x : ndarray, shape (W,), float64
        ``(u - cx) / fx`` of every column.
    ray_y : ndarray, shape (2,), float64
        ``(1 / fy, -cy / fy)``: the ray's y is ``v / fy - cy / fy``.
    plane : ndarray, shape (4,), float64
        Laser plane in the camera frame: unit normal and offset (m).
    sensor_from_cam : ndarray, shape (3, 4), float64
        Rotation and translation (m), camera to sensor frame.
    min_range_m, max_range_m : float
        The laser's range band, m.
    out : ndarray, shape (4, W), float64
        Written: x_m, y_m, range_m, bearing_deg (sensor frame, bearing positive left);
        NaN where the row is NaN or the ray misses the plane (in front of the camera).
    in_band : ndarray, shape (W,), bool
        Written: whether the range lies in ``[min_range_m, max_range_m]``.
    """
    cdef Py_ssize_t n = v_px.shape[0], u
    cdef double v, rx, ry, den, s, cx, cy, cz, x, y, r
    if ray_x.shape[0] < n or out.shape[0] != 4 or out.shape[1] != n or in_band.shape[0] != n \
            or ray_y.shape[0] != 2 or plane.shape[0] != 4 or sensor_from_cam.shape[0] != 3 \
            or sensor_from_cam.shape[1] != 4:
        raise ValueError("triangulate_columns: v_px (W,), ray_x (W,), ray_y (2,), plane (4,), "
                         "sensor_from_cam (3, 4), out (4, W), in_band (W,)")
    cdef double m00 = sensor_from_cam[0, 0], m01 = sensor_from_cam[0, 1]
    cdef double m02 = sensor_from_cam[0, 2], m03 = sensor_from_cam[0, 3]
    cdef double m10 = sensor_from_cam[1, 0], m11 = sensor_from_cam[1, 1]
    cdef double m12 = sensor_from_cam[1, 2], m13 = sensor_from_cam[1, 3]
    with nogil:
        for u in range(n):
            out[0, u] = NAN
            out[1, u] = NAN
            out[2, u] = NAN
            out[3, u] = NAN
            in_band[u] = False
            v = v_px[u]
            if not isfinite(v):
                continue
            rx = ray_x[u]
            ry = v * ray_y[0] + ray_y[1]
            den = plane[0] * rx + plane[1] * ry + plane[2]
            if fabs(den) <= 1e-12:
                continue
            s = plane[3] / den
            if not s > 0.0:
                continue
            cx = s * rx
            cy = s * ry
            cz = s
            x = m00 * cx + m01 * cy + m02 * cz + m03
            y = m10 * cx + m11 * cy + m12 * cz + m13
            # (numba's math.hypot: inf when either is, else libm's)
            r = INFINITY if isinf(x) or isinf(y) else hypot(x, y)
            out[0, u] = x
            out[1, u] = y
            out[2, u] = r
            out[3, u] = atan2(y, x) * _DEG_PER_RAD
            in_band[u] = min_range_m <= r <= max_range_m


def covered_shift(const double[::1] r, const double[::1] s, double noise_sigma_dn,
                  double jump_m, double coverage_z, double[::1] shift) -> None:
    """:func:`slitcli.laser.edges.covered_shift_px` into ``shift`` (W,), from the ranges
    ``r`` and strengths ``s`` (W,) float64 (NaN: no stripe), in its arithmetic (numpy's
    expressions, element by element, the same IEEE operations in the same order)."""
    cdef Py_ssize_t w = r.shape[0], i, k, j, d_i
    cdef double d, ref, sk, rk, f, acc, cz_noise = coverage_z * noise_sigma_dn
    cdef bint end, same
    if s.shape[0] != w or shift.shape[0] != w:
        raise ValueError("covered_shift: r, s and shift differ in length")
    with nogil:
        for i in range(w):
            acc = 0.0
            for d_i in range(2):
                d = 1.0 if d_i == 0 else -1.0
                j = i - (1 if d_i == 0 else -1)
                # the outward neighbour: unlit (NaN, also beyond the image) or farther
                end = isfinite(r[i]) and isfinite(s[i]) \
                    and not (0 <= j < w and r[j] <= r[i] + jump_m)
                ref = NAN
                for k in range(1, 4):
                    j = i + (k if d_i == 0 else -k)
                    if not 0 <= j < w:
                        continue
                    rk = r[j]
                    sk = s[j]
                    same = fabs(rk - r[i]) <= jump_m
                    # (np.fmax: a NaN loses to a number)
                    if same and not sk != sk and (ref != ref or sk > ref):
                        ref = sk
                if end and ref > 0:
                    f = s[i] / ref - cz_noise / ref
                    # (np.clip: a NaN stays NaN)
                    if f < 0.0:
                        f = 0.0
                    elif f > 1.0:
                        f = 1.0
                else:
                    f = 1.0
                acc += d * 0.5 * (1.0 - f)
            shift[i] = acc
