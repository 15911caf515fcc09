"""Learning agents for RvEntry-v0: the stable-baselines3 PPO baseline, the DAgger student of the re-planning law, and their plumbing."""
