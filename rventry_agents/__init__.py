"""Learning agents for RvEntry-v0: the stable-baselines3 PPO baseline and its plumbing."""
