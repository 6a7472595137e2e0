"""Independent witness for bayes_accuracy_test.cpp: 1/2 * integral of max(p, q) for two
truncated normals, with scipy.stats.truncnorm and scipy.integrate.quad (Debian's
python3-scipy). Prints one line per case: mean1 std1 lower1 upper1 mean2 std2 lower2 upper2 value.
Run: python3 witness_bayes_accuracy.py"""
import math

from scipy import integrate, stats

CASES = [
    # the paper's 1C interventions of joints 2 and 4, and of joint 6 (tab:singleTrunc), their
    # 0.5 a variance as the paper defines it (std sqrt(0.5)), then read as a std (before
    # sim_dataset_version 3)
    ((-0.75, math.sqrt(0.5), -1.5, 1.5), (0.75, math.sqrt(0.5), -1.5, 1.5)),
    ((2.25, math.sqrt(0.5), 0.0, 3.0), (0.75, math.sqrt(0.5), 0.0, 3.0)),
    ((-0.75, 0.5, -1.5, 1.5), (0.75, 0.5, -1.5, 1.5)),
    ((2.25, 0.5, 0.0, 3.0), (0.75, 0.5, 0.0, 3.0)),
    # the paper's 2C interventions of joint 4, variance 0.4 (tab:twoCamera_trunc)
    ((0.9, math.sqrt(0.4), -1.5, 1.5), (-0.9, math.sqrt(0.4), -1.5, 1.5)),
    # unequal spreads and supports
    ((0.0, 1.0, -2.0, 2.0), (0.5, 0.3, -1.0, 3.0)),
    # identical distributions: chance
    ((0.0, 1.0, -1.0, 1.0), (0.0, 1.0, -1.0, 1.0)),
]


def tn(mean, std, lower, upper):
    return stats.truncnorm((lower - mean) / std, (upper - mean) / std, loc=mean, scale=std)


for p, q in CASES:
    a, b = tn(*p), tn(*q)
    lo, hi = min(p[2], q[2]), max(p[3], q[3])
    points = sorted({p[2], p[3], q[2], q[3]})
    value, _ = integrate.quad(lambda x: max(a.pdf(x), b.pdf(x)), lo, hi, points=points, limit=200)
    print(*p, *q, f"{0.5 * value:.10f}")
