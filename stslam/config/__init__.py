"""The one config edge: the composed config (a plain nested dict) turned into settings dataclasses (SPEC 12).

The entry scripts compose ``conf/`` with Hydra and hand the resolved config,
converted to plain dicts and lists, to :mod:`stslam.experiments`; only that
package and this one read it. Each module here turns the blocks of one
package's concepts into that package's frozen settings dataclasses, checking
every value on the way (:class:`~stslam.errors.ConfigError` ``<full.key>:
expected …``, printed as ``error: …`` with exit code 2):

- :mod:`~stslam.config.readers`: checked getters of one dotted key, and
  :func:`~stslam.config.readers.field_default`;
- :mod:`~stslam.config.robot`: ``sensor`` → :class:`~stslam.robot.sensor.Sensor`;
- :mod:`~stslam.config.sim`: ``world`` → :class:`~stslam.sim.worlds.World`,
  ``door`` → :class:`~stslam.sim.door_trace.DoorScenario`;
- :mod:`~stslam.config.kalman`: ``filter`` → :class:`~stslam.kalman.trace_fit.FilterSettings`;
- :mod:`~stslam.config.selection`: ``selection`` → :class:`~stslam.selection.settings.SelectionSettings`;
- :mod:`~stslam.config.slam`: ``filters.<name>`` → ``stslam.slam.filters.FILTER_PARAMS[name]``
  (A-SLAM: :class:`~stslam.slam.a_slam_settings.ASlamParams`), hinge-axis blocks →
  :class:`~stslam.articulation.hinge_axis.HingeAxisOptions`, ``motion_noise_order``, ``update_iterations``;
- :mod:`~stslam.config.rgbd`: ``frontend`` → :class:`~stslam.rgbd.frontend.TrackerSettings`,
  a data config → :class:`~stslam.rgbd.sequence.SequenceConfig` and
  :class:`~stslam.rgbd.sequence.DataRequest`.

Defaults are stated once, in the dataclasses; the YAML files mirror them
(``tests/config/test_defaults.py`` checks it and lists the deliberate
departures), and a key a config may leave out takes its field's default.

Why hand-written readers and not Hydra structured configs (dataclass schemas
in a ConfigStore, checked by omegaconf at every composition and override):

- Our error lines are part of the interface (README, ``tests/e2e/test_cli_errors.py``):
  ``n_seeds: expected an integer, got 'abc'``, ``tau: expected a number > 0.0
  and < 1.0, got 1.5``. omegaconf reports a type mismatch in its own multi-line
  words, at composition time, and knows no ranges at all; we would still need
  every range check here, and would have to rewrite its messages.
- Many checks involve more than one field or value: ``depth_max_m`` above
  ``depth_min_m``, the spring rest angle below the closed angle, ``init_window
  ≥ order + 2``, ``order ≤ n_min − 2``, increasing keyframes, distinct model
  names, unit directions, ``null`` meaning "no guard" (inf) or "off" (None).
  A schema expresses none of them.
- The settings are not schema-shaped: a sensor's field of view is one of two
  dataclasses (omegaconf 2.3 takes unions of primitive types only), several
  settings hold tuples or arrays, a world is built (paths integrated, landmark
  positions computed) rather than copied, and the algorithms' dataclasses
  carry methods and properties, which structured configs do not support. We
  would keep a second, schema-only copy of each class, i.e. every default twice.
- The YAML interpolations we use (``${filters.oracle.sigma_eta_m}``,
  ``${sensor.sigma}``, ``/tuning: ${world}``) work the same without a schema.

What a schema would add, the type check at composition, the readers give too,
one line per bad key, when the experiment starts and before any work. A typo
in a key already fails at composition (Hydra's struct mode: ``bogus: no such
parameter in the configuration``).
"""
