"""The efficiency comparison the convergence studies share (issue 5): the time
one engine needs for a given mean squared error, read off its ladder of
renders at several sample counts, and the machine the studies name."""

import math


def time_for_mse(points, target):
    """points: [(mse, seconds)] of one engine's ladder (two or more); the time it
    needs for MSE `target`: interpolated in log MSE / log time between the two
    ladder points around it (extrapolated from the nearest pair outside the
    ladder). None with fewer than two points."""
    if len(points) < 2:
        return None
    pts = sorted(points)
    pair = next((p for p in zip(pts, pts[1:]) if p[0][0] <= target <= p[1][0] and p[1][0] > p[0][0]), None)
    if pair is None:
        pair = (pts[0], pts[1]) if target < pts[0][0] else (pts[-2], pts[-1])
    (m1, t1), (m2, t2) = pair
    f = (math.log(target) - math.log(m1)) / (math.log(m2) - math.log(m1))
    return math.exp(math.log(t1) + f * (math.log(t2) - math.log(t1)))


def cpu_name():
    """The CPU's model name, as the studies' READMEs name the machine."""
    with open("/proc/cpuinfo") as f:
        return next((l.split(":", 1)[1].strip() for l in f if l.startswith("model name")), "unknown CPU")
