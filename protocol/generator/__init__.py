"""The modules of protocol/generate.py (its entry point, the reference encoder and the CLI):

  definition.py    reads and checks messages.toml and vehicle.toml; the schema hash

Standard library only, as generate.py.
"""
