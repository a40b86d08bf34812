"""The shipped configuration files (YAML data only), addressable by name.

Holds no code: every layer reads these files through its own loader
(:mod:`dss14_env.core.schema`), so nothing here imports anything.
"""
