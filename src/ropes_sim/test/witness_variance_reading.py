#!/usr/bin/python3
"""Witness for InterventionSamplerGolden.FirstSamplesOfEachConfigForSeedZero: the
distribution files' `variance` is read as the paper's variance (sigma = sqrt(x)).

Each draw is the truncated normal's quantile of one Philox uniform, so the same uniform
gave the pins of sim_dataset_version 2 (x read as a standard deviation) and gives today's
(x read as a variance). For each pair below, scipy.stats.truncnorm's CDF of the old pin
under sigma = x and of the new pin under sigma = sqrt(x) must be the same uniform. Also
prints the variance of the paper's 2C TN_[-1.5,1.5](0, 0.4) under both readings (the
number InterventionSampler.TwoCameraAnglesHaveThePapersVariance checks).
Run with Debian's python3 and python3-scipy:
    /usr/bin/python3 src/ropes_sim/test/witness_variance_reading.py
"""
import math

from scipy import stats

# (what, mean, the paper's x, lower, upper, pin of version 2, pin of version 3)
CASES = [
    ("1c_independent do(joint2)=1", -0.75, 0.5, -1.5, 1.5, -0.46689250736474458,
     -0.30024801591874711),
    ("2c_independent joint1", 1.2, 0.4, 0.0, 3.0, 1.0985124158159418, 1.0650618945085879),
    ("2c_independent joint2", 0.0, 0.4, -1.5, 1.5, 0.25202249401103466, 0.39052542784303274),
    ("2c_independent joint3", 0.0, 0.4, -1.5, 1.5, 0.76539831983367768, 1.1369010957542958),
    ("2c_independent joint5", 0.0, 0.4, -1.5, 1.5, -0.82538460351720055, -1.2090579409417079),
    ("2c_independent do(joint1)=1", 2.0, 0.4, 0.0, 3.0, 2.3122365165133223,
     2.4121950060356538),
]


def cdf(x, mean, sigma, lower, upper):
    return stats.truncnorm.cdf(x, (lower - mean) / sigma, (upper - mean) / sigma, loc=mean,
                               scale=sigma)


worst = 0.0
for what, mean, x, lower, upper, old, new in CASES:
    u_old = cdf(old, mean, x, lower, upper)
    u_new = cdf(new, mean, math.sqrt(x), lower, upper)
    worst = max(worst, abs(u_old - u_new))
    print(f"{what}: uniform {u_old:.15f} (sigma = x) {u_new:.15f} (sigma = sqrt(x))")
s = math.sqrt(0.4)
print("TN_[-1.5,1.5](0, 0.4) variance:", stats.truncnorm(-1.5 / s, 1.5 / s, scale=s).var(),
      "(x a variance),", stats.truncnorm(-1.5 / 0.4, 1.5 / 0.4, scale=0.4).var(), "(x a std)")
print(f"largest difference of the uniforms: {worst:.3g}")
raise SystemExit(0 if worst < 1e-12 else 1)
