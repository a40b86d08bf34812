"""Foundations shared by every layer: units, the configuration schema, seeds, statistics
with their intervals, the command's smoothness measures, the result records, output folders
and parallel work items.

May import: third-party libraries (numpy, scipy, PyYAML, threadpoolctl; Ray when installed)
and nothing else of ``dss14_env`` (``docs/architecture.md``).
"""
