"""The simulator: a world, a rover plant, its sensors, a camera and a radio, around the very
firmware core the Uno runs (loaded through its C ABI) and the very host code `rovernav run`
uses against hardware. `rovernav sim` runs it."""
