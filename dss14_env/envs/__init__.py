"""The Gymnasium environments: plant, configuration, scenarios, the single and the vector env.

Nothing heavy is imported here: ``import dss14_env`` registers the ids without building
anything (:func:`dss14_env.envs.presets.register_presets`).
"""
