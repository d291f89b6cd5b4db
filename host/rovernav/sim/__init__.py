"""The simulator: a world, a rover plant, its sensors, a camera and a radio, around the very
firmware core the Uno runs (rovernav.cores: through its C ABI, or the Uno image itself in simavr)
and the very host code `rovernav run` uses against hardware. `rovernav sim` runs it."""
