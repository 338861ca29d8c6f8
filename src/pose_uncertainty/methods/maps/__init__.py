"""Probability maps from the velocity and odometry motion models (Method B).

A map is the probability mass of each cell of a discretised ``(x, y, θ)`` grid
after motion from a known start. Two constructions:

* :func:`single_step_map` — one motion from a known start, the thesis's ``O(n³)``
  case (Němec 2012): the motion-model density is evaluated at every cell centre
  (``mass = p · h² · h_θ``). With ``corrected=False`` (default, as the thesis) it is
  Thrun's density — a density of the *control* noise — normalised to relative
  probability; with ``corrected=True`` the pose-space density of the sampler.
* :func:`multi_step_map` — the prediction step of a histogram filter repeated
  along a trajectory, which the thesis could not compute (``O(n⁶)`` per step by
  brute force). The transition kernel depends on ``x_t − x_{t−1}`` rotated by the
  source heading ``θ_k`` only, so a step is, for every source heading slice, one
  2-D FFT convolution of that slice with a compact kernel that carries every
  destination heading (accumulated in the Fourier domain, one inverse FFT per
  destination slice). Mass that leaves the grid is measured exactly
  (``lost_mass``), and by default the grid grows to hold the spread.

Discretisation
--------------
* Single step: with ``corrected=True`` every cell holds the density *averaged
  over the cell* (each noise factor averaged over the control interval one cell
  spans, see :mod:`pose_uncertainty.methods.motion_models`), so structure thinner than a
  cell (rotation in place, zero variances) is integrated, not aliased. The
  corrected densities have an integrable ``1/r`` singularity at the start pose
  (every turn rate reaches it with zero speed), so the cells within
  :data:`EXACT_RADIUS` of the start are integrated exactly: in control space, a
  1-D quadrature over ``ω̂`` (velocity) or ``δ̂rot1`` (odometry) of the CDF of
  ``V̂`` (``δ̂trans``) between the points where the ray of motion crosses the cell.
  With ``corrected=False`` (Thrun's density, the thesis) cells hold point values.
  A control with *all* variances zero is a deterministic move, deposited
  trilinearly.
* Multi step: the transition kernel is the push-forward of the control noise by
  quadrature (see :func:`multi_step_map`); source mass sits at cell centres.
* Headings cover the full circle ``[−π, π)`` in ``n_θ`` cells.

Modules
-------
``container``    :class:`ProbabilityMap` and its reductions (marginals, regions, moments)
``single_step``  :func:`single_step_map`, the exact one-step map
``multi_step``   :func:`multi_step_map`, the prediction along a trajectory, with grid growth
``transition``   :func:`grid_transition`, the quadrature kernel of one step
``prediction``   :func:`predict_on_grid`, one FFT prediction step on a fixed grid
``step``         one motion step of a model (densities at and over cells)
``kernels``      array kernels shared by the above (ray–cell slabs, deposits, splats)
"""

from .container import ProbabilityMap
from .multi_step import multi_step_map
from .prediction import predict_on_grid
from .single_step import EXACT_RADIUS, single_step_map
from .step import MODELS
from .transition import GridTransition, grid_transition

__all__ = [
    "EXACT_RADIUS",
    "MODELS",
    "GridTransition",
    "ProbabilityMap",
    "grid_transition",
    "multi_step_map",
    "predict_on_grid",
    "single_step_map",
]
