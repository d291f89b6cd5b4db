"""The rover's firmware as the simulator and the tests step it: native.py (its C ABI), uno.py (the Uno image in simavr)."""
