"""The shipped configuration files (YAML data only), addressable by name."""
