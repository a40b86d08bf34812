"""Learned controllers: PPO training (stable-baselines3), trained policies behind the controller
interface, and residual learning on top of the report's PI."""
