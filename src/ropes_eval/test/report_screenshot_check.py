#!/usr/bin/env python3
"""Checks a headless-Chromium screenshot of report.html: the page is not blank and each kind
of plot was drawn. Usage: report_screenshot_check.py SHOT.png

Each kind has its own colours (html_report.cpp), so each check fails alone when its plots are
missing (the pipeline test hides one kind at a time and expects that kind's check to fail):
  - scatter: points in #1f5fa8 (blended with white by their opacity): blue
  - curves: training and label-efficiency lines in #d1495b (red) or #2e933c (green)
  - heat-map: cells from white to rgb(230, 120, 20): orange
  - images: PNG images (occlusion figure, intervention grid): 8x8 blocks of one grey level
    between black and white, which anti-aliased text never gives
Exit 0 when all hold, 1 with each failing check named ("FAILED: <name>").
"""
import sys

from PIL import Image


def main():
    im = Image.open(sys.argv[1]).convert("RGB")
    w, h = im.size
    px = im.load()
    counts = {"non-white": 0, "scatter": 0, "curves": 0, "heat-map": 0, "images": 0}
    for y in range(0, h, 2):
        for x in range(0, w, 2):
            r, g, b = px[x, y]
            if (r, g, b) != (255, 255, 255):
                counts["non-white"] += 1
            if b > r + 40 and b > g + 20:
                counts["scatter"] += 1
            if (r > 180 and 50 < g < 110 and 70 < b < 130) or (r < 80 and g > 120 and b < 90):
                counts["curves"] += 1
            if r > 200 and r > g + 40 and g > b + 30:
                counts["heat-map"] += 1
    for y in range(0, h - 8, 8):
        for x in range(0, w - 8, 8):
            c = px[x, y]
            if c[0] == c[1] == c[2] and 10 < c[0] < 245 and all(
                    px[x + dx, y + dy] == c for dx, dy in ((7, 0), (0, 7), (7, 7), (3, 4))):
                counts["images"] += 1
    sampled = (w // 2) * (h // 2)
    checks = {
        "not blank (at least 2 % of the page is not white)": counts["non-white"] > 0.02 * sampled,
        "scatter (at least 1000 samples of blue points)": counts["scatter"] >= 1000,
        "curves (at least 100 samples of red or green lines)": counts["curves"] >= 100,
        "heat-map (at least 300 samples of orange cells)": counts["heat-map"] >= 300,
        "images (at least 30 uniform grey 8x8 blocks)": counts["images"] >= 30,
    }
    print(f"{sys.argv[1]}: {w}x{h}; " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    failed = [name for name, ok in checks.items() if not ok]
    for name in failed:
        print(f"FAILED: {name}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
