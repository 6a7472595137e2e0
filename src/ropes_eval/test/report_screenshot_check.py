#!/usr/bin/env python3
"""Checks a headless-Chromium screenshot of report.html: the page is not blank and its plots
were drawn. Usage: report_screenshot_check.py SHOT.png

What counts as drawn (the report's own colours, html_report.cpp):
  - scatter points and the first curve series: #1f5fa8 (blended with white by opacity)
  - the second series (a training curve or ROPES' line): #d1495b
  - the heat map's cells: shades between white and rgb(31, 95, 168)
  - the images (occlusion figure, intervention grid): grey pixels of many levels
Exit 0 when all hold, 1 with the failing check named.
"""
import sys

from PIL import Image


def main():
    im = Image.open(sys.argv[1]).convert("RGB")
    w, h = im.size
    px = im.load()
    ink = red = blue_cells = 0
    greys = set()
    non_white = 0
    for y in range(0, h, 2):
        for x in range(0, w, 2):
            r, g, b = px[x, y]
            if (r, g, b) != (255, 255, 255):
                non_white += 1
            # the ink, alone or blended with white at opacity >= 0.4
            if b > r + 40 and b > g + 20 and r < 170 and abs((255 - r) / 224 - (255 - b) / 87) < 0.6:
                ink += 1
            if r > 180 and 50 < g < 110 and 70 < b < 130:
                red += 1
            if r == g == b:
                greys.add(r)
            if b > 160 and b > r + 30 and g > r and (255 - r) > 20:
                blue_cells += 1
    sampled = (w // 2) * (h // 2)
    checks = {
        "not blank (at least 2 % of the page is not white)": non_white > 0.02 * sampled,
        "scatter points and curves in #1f5fa8 (at least 2000 samples)": ink >= 2000,
        "a second series in #d1495b (at least 100 samples)": red >= 100,
        "heat-map cells (at least 500 samples)": blue_cells >= 500,
        "images: at least 64 grey levels": len(greys) >= 64,
    }
    failed = [name for name, ok in checks.items() if not ok]
    print(f"{sys.argv[1]}: {w}x{h}; non-white {non_white}/{sampled}, ink {ink}, red {red}, "
          f"heat-map {blue_cells}, grey levels {len(greys)}")
    for name in failed:
        print(f"FAILED: {name}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
