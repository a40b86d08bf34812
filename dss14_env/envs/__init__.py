"""The Gymnasium environments: plant, configuration, scenarios, the step, the single and the
vector env, and the presets behind the registered ids.

May import: ``wind``, ``model``, ``core`` (``docs/architecture.md``).

Nothing heavy is imported here: ``import dss14_env`` registers the ids without building
anything (:func:`dss14_env.envs.presets.register_presets`).
"""
