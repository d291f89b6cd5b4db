"""What the camera looks for in a set-up besides the locator's settings: the arena's four corner
tags, and the colour words the markers' stickers go by.

`rovernav calibrate camera` finds the arena by the corner tags and names the markers by the
colour words (`--front orange`); `rovernav calibrate tags` draws the tags to print; the
simulator's set-ups (rovernav.sim.setup) draw the same tags and pick their markers' colours
from the same words.
"""

from __future__ import annotations

CORNER_TAG_IDS = (10, 11, 12, 13)  # bottom-left, bottom-right, top-right, top-left
CORNER_DICTIONARY = "DICT_4X4_50"
CORNER_INSET_M = 0.07  # each corner tag's centre this far in from both walls

#: Colour words and their hue bands (OpenCV H, 0-179), as colour_markers.hue_name names a hue.
COLOUR_BANDS = {
    "orange": (7.5, 24.0),
    "yellow": (24.0, 35.0),
    "green": (35.0, 80.0),
    "cyan": (80.0, 100.0),
    "blue": (100.0, 130.0),
    "purple": (130.0, 150.0),
    "magenta": (150.0, 170.0),
}
