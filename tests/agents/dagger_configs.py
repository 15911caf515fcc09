"""Small DAgger configurations the tests share: seconds, not hours, with the lqr law as the expert."""

SMALL = """
[student]
hidden = [16, 16]
load_relief_margin = 0.02
[expert]
agent = "lqr"
[data]
dispersion = "standard"
train_seed = 2_000_000
[[rounds]]
episodes = 2
beta = 1.0
[[rounds]]
episodes = 1
beta = 0.5
[fit]
epochs = 3
batch_size = 512
learning_rate = 1e-3
seed = 0
[select]
episodes = 3
seed = 100_000
dispersion = "standard"
[final]
members = 2
[deploy]
tracking = [[3.0, 2.0]]
tracking_descent_mps = 2500.0
"""

DISTIL = "[distil]\nhidden = [8]\nepochs = 2\nemphasis_below_m = 20_000.0\nemphasis = 3\n"
