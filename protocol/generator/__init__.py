"""The modules of protocol/generate.py (its entry point, the reference encoder and the CLI):

  definition.py    reads and checks messages.toml and vehicle.toml; the schema hash
  emit_cpp.py      firmware/lib/link/messages_gen.h and firmware/test/test_link/vectors_gen.h
  emit_python.py   host/rovernav/link/messages_gen.py
  emit_vehicle.py  firmware/lib/link/vehicle_gen.h and host/rovernav/vehicle_gen.py

Standard library only, as generate.py.
"""
