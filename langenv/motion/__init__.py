"""The arm's 500 Hz tick: :class:`~langenv.motion.tick.GuidedArm` composes the arm, the guide, the
admittance, the sensor, the cooperation, ``t_x`` and the safety limits (``tick.py``); its
compiled twin beside it (``tick_kernels.py``: ``TICK``, ``tick``), bound by
:class:`~langenv.motion.compiled_tick.CompiledTick` (``compiled_tick.py``)."""
