#!/usr/bin/python3
"""Witness for TruncatedNormalGolden in test/truncated_normal_test.cpp.

Feeds the pinned uniforms of PhiloxStream(seed 7, stream 0) through
scipy.stats.truncnorm.ppf and prints scipy's draws beside the pinned ones.
Run with Debian's python3 and python3-scipy:
    /usr/bin/python3 src/ropes_core/test/witness_truncated_normal.py
"""
import scipy.stats as st

uniforms = [0.95459712855631274, 0.11417736176891524, 0.40696040388408328, 0.17179867593835429]
pinned = {
    (0.0, 1.0, -1.5, 1.5): [1.2473008924606452, -0.97118201927582171, -0.20344955815934615,
                            -0.78696526577298098],
    (2.25, 0.5, 0.0, 3.0): [2.8654592343581626, 1.6274636159010085, 2.0969635010112246,
                            1.7534366382739774],
    (0.0, 1.0, 6.0, 7.0): [6.4794931666913449, 6.0196287491940703, 6.0841358422717811,
                           6.0304906657329855],
}
worst = 0.0
for (mu, sigma, lower, upper), draws in pinned.items():
    for u, ours in zip(uniforms, draws):
        ref = st.truncnorm.ppf(u, (lower - mu) / sigma, (upper - mu) / sigma, loc=mu, scale=sigma)
        worst = max(worst, abs(ref - ours))
        print(f"TN[{lower},{upper}]({mu},{sigma}) u={u:.17g} scipy={ref:.17g} ours={ours:.17g}")
print(f"largest difference {worst:.3g}")
raise SystemExit(0 if worst < 1e-13 else 1)
