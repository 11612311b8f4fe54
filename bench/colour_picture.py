#!/usr/bin/env python3
"""The picture of docs/colour.md: the top views `colour_eval --out DIR` writes (observed_T.png,
predicted_T.png, latest_T.png for T = morning, evening: the test sessions nearest 09:30 and 20:30)
tiled into one picture with labels: a row per session, observed | predicted by the colour model |
latest colour.

Usage: /usr/bin/python3 bench/colour_picture.py DIR OUT.png MORNING_LABEL EVENING_LABEL
  (the labels name the sessions' times, e.g. "09:33" "20:43")
"""
import sys
from pathlib import Path

from PIL import Image, ImageDraw


def main():
    src, out = Path(sys.argv[1]), Path(sys.argv[2])
    rows = []
    for hour in ("morning", "evening"):
        tiles = [Image.open(src / f"{kind}_{hour}.png").convert("RGB") for kind in ("observed", "predicted", "latest")]
        rows.append((hour, tiles))
    w = max(t.width for _, tiles in rows for t in tiles)
    h = max(t.height for _, tiles in rows for t in tiles)
    pad, label = 6, 18
    canvas = Image.new("RGB", (3 * w + 4 * pad, 2 * (h + label) + 3 * pad), "white")
    draw = ImageDraw.Draw(canvas)
    labels = {"morning": sys.argv[3], "evening": sys.argv[4]}
    names = ("observed at {h} (test session)", "predicted for {h} (colour model)", "latest colour (baseline)")
    for r, (hour, tiles) in enumerate(rows):
        y = pad + r * (h + label + pad)
        for c, tile in enumerate(tiles):
            x = pad + c * (w + pad)
            draw.text((x, y), names[c].format(h=labels[hour]), fill="black")
            canvas.paste(tile, (x, y + label))
    canvas.save(out)


if __name__ == "__main__":
    main()
