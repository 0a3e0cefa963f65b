"""Articulated bodies: points that move with one joint share one motion state and one model (SPEC 13).

A body is founded by a landmark converted to an articulated block (its *founder*); the
founder's block holds the body's motion state X = [q, q⁽¹⁾, …] on the founder's structure.
Other landmarks join as *members*: they have no block of their own, only an
:class:`~stslam.slam.blocks.ArticulatedBlock` on their own structure in the body's q that
reads the founder's slice of the state, so each member's observation updates the body's q
through ∂p_i/∂q (SPEC 13, 5.3). A landmark alone is a body of one point.

One concept, one package:

* :mod:`~stslam.slam.bodies.decisions` — **which model a landmark or body is, and when it
  switches**: the selector's verdict, the conversion's model, revisions, and the window
  evidence they read. Every model decision of A-SLAM is made there.
* :mod:`~stslam.slam.bodies.joint` — the kinematics of a member on its body's joint and the
  tests of rigid motion (pure functions on arrays).
* :mod:`~stslam.slam.bodies.grouping` — who joins which body, and re-anchoring members when
  the founder's block changes.
* :mod:`~stslam.slam.bodies.state` — the member table, and the EKF state whose members read
  their founder's slice (the factor graph's counterpart is
  :class:`stslam.graph.bodies.GraphBodyState`, which builds on the same table).
* :mod:`~stslam.slam.bodies.policy` — :class:`BodyLandmarkPolicy`, which carries out the
  decisions and the grouping on either back end.

Import from the modules (this package's ``__init__`` imports nothing, so that the landmark
policy can use the decisions without an import cycle).
"""
