"""The dynamics: integrators, the constraint machinery, simulation, the compiled kernels' stepper and
configuration, and the numerical helpers they share (docs/physics.md). The models are in
:mod:`mbs_envs.models`."""
