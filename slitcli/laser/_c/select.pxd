"""Order statistics of a buffer of doubles, shared by the laser's compiled modules (the
evidence's noise medians, the tests' laser colour and width spread): inlined into each
module that cimports them. The values are order statistics, so any selection gives the
same bits as ``np.median``/``np.sort`` (no NaN among them)."""


cdef inline void select_kth(double* a, Py_ssize_t m, Py_ssize_t k) noexcept nogil:
    """Reorder ``a[:m]`` so that ``a[k]`` holds its ``k``-th smallest value, none before
    it larger, none after it smaller (quickselect; median-of-three pivots)."""
    cdef Py_ssize_t lo = 0, hi = m - 1, i, j, mid
    cdef double p, t
    while hi > lo:
        mid = lo + (hi - lo) // 2
        # order a[lo], a[mid], a[hi]; the median of the three is the pivot
        if a[mid] < a[lo]:
            t = a[mid]; a[mid] = a[lo]; a[lo] = t
        if a[hi] < a[lo]:
            t = a[hi]; a[hi] = a[lo]; a[lo] = t
        if a[hi] < a[mid]:
            t = a[hi]; a[hi] = a[mid]; a[mid] = t
        p = a[mid]
        i = lo
        j = hi
        while i <= j:
            while a[i] < p:
                i += 1
            while p < a[j]:
                j -= 1
            if i <= j:
                t = a[i]; a[i] = a[j]; a[j] = t
                i += 1
                j -= 1
        # a[lo..j] <= p <= a[i..hi], and a[j+1..i-1] == p
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            return


cdef inline double median_inplace(double* a, Py_ssize_t n) noexcept nogil:
    """The median of ``a[:n]`` (n >= 1, no NaN; reorders ``a``) as numpy's: the mean of
    the two middle values of an even count, ``(a + b) / 2``."""
    cdef Py_ssize_t half = n >> 1, j
    cdef double lo, hi
    if n & 1:
        select_kth(a, n, half)
        return a[half]
    select_kth(a, n, half - 1)
    lo = a[half - 1]
    # nothing after position half - 1 is smaller: the next order statistic is their least
    hi = a[half]
    for j in range(half + 1, n):
        if a[j] < hi:
            hi = a[j]
    return (lo + hi) / 2
