"""Foundations shared by every layer: units and labels, the configuration schema."""
