"""The flat optimizer's NLP for Ipopt: the per-sample library and CasADi's exact derivatives of
the rest, assembled into the values, gradient, Jacobian and Hessian of the Lagrangian.

The transcription writes the objective f and the constraints g as expressions of the decision
variables x, the parameters p and symbols Y standing for every sample's outputs y(P_j)
(:data:`cpopt.flatopt.samples.OUTPUTS`), where P_j, the sample's lifted CP derivatives, are part
of x. Everything but y is cheap: CasADi differentiates it exactly, with Y as an input. The chain
rule joins the two parts; with L(x, Y) = lam_f f + lam_g' g and JY the
Jacobian of the samples' outputs (block diagonal, from the library)

* grad f = f_x + JY' f_Y, jac g = g_x + g_Y JY,
* hess L = L_xx + (L_xY JY + JY' L_Yx) + JY' L_YY JY + sum_i mu_i hess y_i, mu = L_Y.

The last two terms are one 10 x 10 block per sample, computed by the compiled library
(``sample_hess``; ``sample_gn`` leaves out the curvature of y). L_xY is not empty only when the
objective's weights depend on x (free times): then its cross terms are added.

The cheap part is differentiated as the MX graph the transcription wrote, not expanded to SX.
Its rows are mostly nonlinear in x although the lifted samples are linear in a phase's
coefficients: the boundary coefficients come from the nodes' values through the flat map (and
free times scale them by powers of the phase's length), so each row adds to the Hessian in the
14-30 core variables (measured: 741 of transfer_min_torque's 795 rows, 1482 of
swing_up_min_time's 1789).
The graph is a few hundred matrix operations (sparse basis matrices times a phase's few
coefficients); expanded, it is 25 000-60 000 scalar operations, and the SX Hessian of the
Lagrangian, 100 000-400 000, took 0.15-0.65 s to build for every pattern of signs and every
refinement, most of a bundled problem's planning. Measured in-process on two idle cores (SX
against MX, planning time): transfer_min_torque 0.69 / 0.40 s, swing_up_min_time 3.07 / 1.75 s
(three builds), swing_up_switches 5.65 / 3.98 s, swing_up_path_timing 1.94 / 1.15 s; an MX
evaluation costs about as much as the SX one (the Hessian 1.9 ms against 1.7 ms an iteration on
swing_up_switches). The same optimum to 1e-9 relative; Ipopt's iteration counts differ in the
rounding, like any change of the derivatives' arithmetic.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..model.robot import Arm
from .samples import NY, arm_vector, sample_library

CURVATURE = ("all", "none")
"""Curvature of the samples' outputs kept in the Hessian: ``all`` (exact) or ``none``
(Gauss-Newton: J' L_YY J alone; keeping the curvature of the constraint rows was measured no
better, see ``optimizer.solver.hessian`` in docs/problems.md)."""


@dataclass(frozen=True)
class SampleBlock:
    """One phase's samples: lifted CP derivatives in x, the symbols of their outputs, signs.

    Attributes
    ----------
    P : casadi.MX
        The lifted CP derivatives (2 x 5n), sample j in columns 5j..5j+4; a symbol in x.
    Y : casadi.MX
        Symbols standing for the samples' outputs (9 x n).
    sigma : numpy.ndarray
        The sign of gamma at each sample (n,).
    """

    P: ca.MX
    Y: ca.MX
    sigma: np.ndarray


@dataclass(frozen=True)
class Assembled:
    """The NLP's functions of (x, p) for nlpsol, and the samples' outputs.

    Attributes
    ----------
    f, g : casadi.MX
        Objective and constraints as expressions of x and p.
    options : dict
        nlpsol options: ``grad_f``, ``jac_g``, ``hess_lag`` and what they need.
    outputs : casadi.Function
        ``(x, p) -> Y`` (9 x N), the samples' outputs at x.
    """

    f: ca.MX
    g: ca.MX
    options: dict
    outputs: ca.Function


def _block_diagonal(values: ca.MX, block: ca.Sparsity, count: int) -> ca.MX:
    """count blocks of one sparsity side by side (a mapped function's output) as a block
    diagonal matrix (their nonzeros are in the same order)."""
    return ca.sparsity_cast(values, ca.diagcat(*([block] * count)))


def _cheap_functions(x, p, Y, f, g) -> dict[str, ca.Function]:
    """The functions of everything but the samples' outputs and their derivatives with respect
    to x and Y (see the module docstring), differentiated on the transcription's MX graph."""
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", g.numel())
    y = ca.vec(Y)
    count = Y.shape[1]
    lag = lam_f * f + ca.dot(lam_g, g)
    mu = ca.gradient(lag, y)
    Hyy = ca.jacobian(mu, y)
    W = ca.horzcat(*[Hyy[NY * j : NY * (j + 1), NY * j : NY * (j + 1)] for j in range(count)])
    Hxx, lag_x = ca.hessian(lag, x)
    hess_ins = [x, p, Y, lam_f, lam_g]
    hess_outs = [ca.triu(Hxx), ca.reshape(mu, NY, count), ca.densify(W)]
    hess_outs.append(ca.jacobian(lag_x, y))
    return {
        "value": ca.Function("cheap_value", [x, p, Y], [f, g]),
        "grad": ca.Function("cheap_grad", [x, p, Y], [f, ca.gradient(f, x), ca.gradient(f, y)]),
        "jac": ca.Function("cheap_jac", [x, p, Y], [g, ca.jacobian(g, x), ca.jacobian(g, y)]),
        "hess": ca.Function("cheap_hess", hess_ins, hess_outs),
    }


@dataclass(frozen=True)
class _Samples:
    """The samples as seen from x: P(x), signs, the arm's parameters, the library."""

    S: ca.DM  # x -> vec(P): a selection of x (the blocks lie in x in this order)
    P: ca.MX
    sigma: ca.DM
    arm: ca.DM
    count: int
    library: dict

    def map(self, name: str, *extra) -> list:
        """The outputs of the library's function ``name`` over every sample."""
        mapped = self.library[name].map(self.count)
        return mapped.call([self.P, self.sigma, self.arm, *extra])

    def jacobian(self, J: ca.MX) -> ca.MX:
        """d vec(Y)/dx (9N x nx) from the mapped Jacobians J (9 x 10N)."""
        blocks = _block_diagonal(J, self.library["sample_jac"].sparsity_out(1), self.count)
        return ca.mtimes(blocks, self.S)


def _samples(x: ca.MX, blocks: list[SampleBlock], arm: Arm) -> _Samples:
    lifted = ca.vec(ca.horzcat(*[b.P for b in blocks]))
    S = ca.DM(ca.Function("s", [x], [ca.jacobian(lifted, x)]).sparsity_out(0), 1.0)
    count = sum(b.Y.shape[1] for b in blocks)
    return _Samples(
        S=S,
        P=ca.reshape(ca.mtimes(S, x), 2, 5 * count),
        sigma=ca.DM(np.concatenate([b.sigma for b in blocks])).T,
        arm=ca.DM(arm_vector(arm)),
        count=count,
        library=sample_library(arm.kind).functions,
    )


def _hessian(x, p, cheap: dict, samples: _Samples, curvature: str) -> ca.Function:
    """``hess_lag(x, p, lam_f, lam_g)``: the upper triangle of the Hessian of the Lagrangian."""
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", cheap["value"].size1_out(1))
    coupled = cheap["hess"].sparsity_out(3).nnz() > 0  # objective weights depend on x
    y, J = samples.map("sample_jac") if coupled else (samples.map("sample")[0], None)
    Hxx, mu, W, Hxy = cheap["hess"](x, p, y, lam_f, lam_g)
    if curvature == "none":
        block = samples.library["sample_gn"].sparsity_out(0)
        per_sample = samples.map("sample_gn", W)[0]
    else:
        block = samples.library["sample_hess"].sparsity_out(0)
        per_sample = samples.map("sample_hess", mu, W)[0]
    HB = _block_diagonal(per_sample, block, samples.count)
    H = Hxx + ca.mtimes(samples.S.T, ca.mtimes(HB, samples.S))
    if coupled:
        cross = ca.mtimes(Hxy, samples.jacobian(J))
        H = H + ca.triu(cross + cross.T)
    return ca.Function("hess_lag", [x, p, lam_f, lam_g], [H])


def assemble(
    x: ca.MX,
    p: ca.MX,
    f: ca.MX,
    g: ca.MX,
    blocks: list[SampleBlock],
    arm: Arm,
    curvature: str = "all",
) -> Assembled:
    """Assemble the NLP's functions (see the module docstring).

    Parameters
    ----------
    x, p : casadi.MX
        Decision variables (the blocks' P among them) and parameters.
    f, g : casadi.MX
        Objective and constraints, expressions of x, p and the blocks' Y.
    blocks : list of SampleBlock
        The samples, by phase.
    arm : Arm
        The arm (its parameters are the library's inputs).
    curvature : str
        One of :data:`CURVATURE`.
    """
    if curvature not in CURVATURE:
        raise ValueError(f"curvature must be one of {CURVATURE}, got {curvature!r}")
    Y = ca.horzcat(*[b.Y for b in blocks])
    samples = _samples(x, blocks, arm)
    cheap = _cheap_functions(x, p, Y, f, g)
    y = samples.map("sample")[0]
    f_x, g_x = cheap["value"](x, p, y)
    y_jac, J = samples.map("sample_jac")
    JY = samples.jacobian(J)
    f_j, fx, fy = cheap["grad"](x, p, y_jac)  # sample_jac's y: one library call, not two
    gj, gx, gy = cheap["jac"](x, p, y_jac)
    options = {
        "grad_f": ca.Function("grad_f", [x, p], [f_j, fx + ca.mtimes(JY.T, fy)]),
        "jac_g": ca.Function("jac_g", [x, p], [gj, gx + ca.mtimes(gy, JY)]),
        "hess_lag": _hessian(x, p, cheap, samples, curvature),
        # the library has no CasADi derivatives: nlpsol must not differentiate f or g itself
        "expand": False,
        "no_nlp_grad": True,
        "calc_lam_p": False,
    }
    return Assembled(f_x, g_x, options, ca.Function("outputs", [x, p], [y]))
