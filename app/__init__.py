"""Shared-control platform: policy blending (Dragan & Srinivasa 2013) on a simulated 7-DoF arm.

Subpackages:
    app.blending  the formalism, pure numpy (prediction, confidence, arbitration, policy, blend)
    app.robot     the arm (MuJoCo physics + pinocchio kinematics) and its scenes
    app.teleop    input devices -> the user's next configuration U, interface reach
    app.trial     one trial: input -> blending -> robot, headless or paced

Every error ``app`` raises derives from ``app.errors.AppError``.

``app`` imports nothing from ``study`` or ``analysis``: the study server, protocols and the
store live in ``study``.
"""

__version__ = "0.1.0"
