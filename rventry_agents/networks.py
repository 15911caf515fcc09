"""The imitation student's networks (torch): one MLP, or an ensemble whose commands are the mean.

Torch loads only with this module, which :mod:`rventry_agents.imitation` imports when a network
is first built or read. A saved network is self-describing: :func:`save_bytes` writes its widths,
its member count and the names of the features it reads beside the weights, so
:func:`load_bytes` rebuilds it without any other file and refuses one trained on features in
another order.
"""

from __future__ import annotations

import io

import torch
from torch import nn

FORMAT = "rventry-student-1"


class Student(nn.Module):
    """An MLP from the inputs to the three commands, standardized on both sides (buffers set from
    the data by the fit)."""

    def __init__(self, n_inputs: int, hidden: tuple[int, ...]):
        super().__init__()
        self.hidden = tuple(int(h) for h in hidden)
        self.register_buffer("mean", torch.zeros(n_inputs))
        self.register_buffer("std", torch.ones(n_inputs))
        self.register_buffer("out_mean", torch.zeros(3))
        self.register_buffer("out_scale", torch.ones(3))
        layers, width = [], n_inputs
        for h in self.hidden:
            layers += [nn.Linear(width, h), nn.Tanh()]
            width = h
        layers += [nn.Linear(width, 3)]
        self.body = nn.Sequential(*layers)

    @property
    def n_members(self) -> int:
        return 1

    def forward(self, x):
        """The commands, standardized; :meth:`commands` gives them in their own units."""
        return self.body((x - self.mean) / self.std)

    def commands(self, x):
        return self.forward(x) * self.out_scale + self.out_mean


class Ensemble(nn.Module):
    """Members of one architecture; the commands are the mean of theirs."""

    def __init__(self, n_inputs: int, hidden: tuple[int, ...], members: int):
        super().__init__()
        self.hidden = tuple(int(h) for h in hidden)
        self.members = nn.ModuleList(Student(n_inputs, hidden) for _ in range(int(members)))

    @property
    def n_members(self) -> int:
        return len(self.members)

    def commands(self, x):
        return torch.stack([m.commands(x) for m in self.members]).mean(0)


def build(n_inputs: int, hidden: tuple[int, ...], members: int = 1) -> Student | Ensemble:
    """One :class:`Student`, or an :class:`Ensemble` of ``members`` > 1."""
    if isinstance(members, bool) or int(members) != members or int(members) < 1:
        raise ValueError(f"a student needs at least one member network, got members = {members!r}")
    if not hidden or any(int(h) < 1 for h in hidden):
        raise ValueError(f"a student needs hidden layer widths >= 1, got {hidden!r}")
    return Student(n_inputs, hidden) if int(members) == 1 else Ensemble(n_inputs, hidden, int(members))


def save_bytes(network: Student | Ensemble, inputs: tuple[str, ...]) -> bytes:
    """The network as bytes: its architecture, the names of its ``inputs`` in order, and its weights."""
    buf = io.BytesIO()
    torch.save({"format": FORMAT, "hidden": list(network.hidden), "members": network.n_members,
                "inputs": list(inputs), "state_dict": network.state_dict()}, buf)  # fmt: skip
    return buf.getvalue()


def load_bytes(data: bytes, inputs: tuple[str, ...], hidden=None, members=None) -> Student | Ensemble:
    """A network from :func:`save_bytes`, checked against the ``inputs`` this package now builds.

    A bare state dict (the format before networks described themselves) needs ``hidden`` and
    ``members``, and is taken to read ``inputs``.

    :raises ValueError: the file's inputs differ from ``inputs`` (named), or its architecture
        from a given ``hidden`` / ``members``, or it is no student network.
    """
    try:
        blob = torch.load(io.BytesIO(data), weights_only=True)
    except Exception as exc:  # empty, truncated or foreign bytes: torch raises several kinds
        raise ValueError(f"these bytes hold no student network ({type(exc).__name__}: {str(exc)[:200]})") from None
    if isinstance(blob, dict) and blob.get("format") == FORMAT:
        saved = tuple(blob["inputs"])
        if saved != tuple(inputs):
            moved = [f"{name!r} (index {i} saved, {inputs.index(name) if name in inputs else 'absent'} now)"
                     for i, name in enumerate(saved) if i >= len(inputs) or inputs[i] != name]  # fmt: skip
            raise ValueError(
                "this network was trained on input features in another order or set than this package builds: "
                + "; ".join(moved[:6]) + (f"; and {len(moved) - 6} more" if len(moved) > 6 else "")
            )
        for name, given, found in (("hidden", hidden, tuple(blob["hidden"])), ("members", members, blob["members"])):
            if given is not None and (tuple(given) if name == "hidden" else int(given)) != found:
                raise ValueError(f"the saved network has {name} = {found}, not the {given} asked for")
        hidden, members, state = tuple(blob["hidden"]), int(blob["members"]), blob["state_dict"]
    elif isinstance(blob, dict) and all(isinstance(v, torch.Tensor) for v in blob.values()):
        if hidden is None or members is None:
            raise ValueError("a bare state dict needs its hidden widths and member count (student.json)")
        state = blob
    else:
        raise ValueError("these bytes hold no student network")
    net = build(len(inputs), tuple(hidden), int(members))
    try:
        net.load_state_dict(state)
    except RuntimeError as exc:  # weights of other shapes than the architecture it names
        raise ValueError(f"the saved weights do not fit a student of hidden = {list(hidden)}, members = {members}: "
                         f"{str(exc)[:300]}") from None  # fmt: skip
    return net


__all__ = ["FORMAT", "Student", "Ensemble", "build", "save_bytes", "load_bytes"]
