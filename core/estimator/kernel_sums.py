"""Sums the kernel makes as numpy and math.fsum make them, so its values equal theirs.

A window's mean wrench (:func:`pairwise_sum`, numpy's pairwise order) and the mean of a still
run's window means (:func:`exact_mean`, compensated as math.fsum is exact) decide the zero
(:mod:`.kernel_zero`); summed in another order they would differ in the last bits from the
zero Python took before the kernel judged the windows, and the golden file's outputs with
them.
"""

from __future__ import annotations

import numpy as np

from hapticdesk.estimator.kernel_compile import compiled, inlined


@inlined
def exact_mean(sf: np.ndarray, base: int, first: int, n: int, ring: int) -> float:
    """The mean of n values sf[base + 6·((first + j) mod ring)], summed with Neumaier's
    compensation: for the default two windows the correctly rounded sum, as zero.py's
    math.fsum; for more, the same to rounding."""
    total = 0.0
    small = 0.0
    for j in range(n):
        at = first + j
        if at >= ring:
            at -= ring
        x = sf[base + 6 * at]
        t = total + x
        if abs(total) >= abs(x):
            small += (total - t) + x
        else:
            small += (x - t) + total
        total = t
    return (total + small) / n


@compiled
def pairwise_sum(a: np.ndarray, start: int, n: int, stride: int) -> float:
    """Σ a[start + j·stride] for j < n, summed as numpy sums a contiguous axis (pairwise, 8
    lanes), so a window's mean is numpy's to the last bit."""
    if n < 8:
        res = 0.0
        for j in range(n):
            res += a[start + j * stride]
        return res
    if n <= 128:
        r0 = a[start]
        r1 = a[start + stride]
        r2 = a[start + 2 * stride]
        r3 = a[start + 3 * stride]
        r4 = a[start + 4 * stride]
        r5 = a[start + 5 * stride]
        r6 = a[start + 6 * stride]
        r7 = a[start + 7 * stride]
        j = 8
        while j < n - (n % 8):
            b = start + j * stride
            r0 += a[b]
            r1 += a[b + stride]
            r2 += a[b + 2 * stride]
            r3 += a[b + 3 * stride]
            r4 += a[b + 4 * stride]
            r5 += a[b + 5 * stride]
            r6 += a[b + 6 * stride]
            r7 += a[b + 7 * stride]
            j += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while j < n:
            res += a[start + j * stride]
            j += 1
        return res
    n2 = n // 2
    n2 -= n2 % 8
    return pairwise_sum(a, start, n2, stride) + pairwise_sum(a, start + n2 * stride, n - n2, stride)
