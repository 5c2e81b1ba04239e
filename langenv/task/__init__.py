"""The learning task's interface: what a policy observes (:mod:`langenv.task.observation`, the
one home the env and the policies read through) and what it is scored by
(:mod:`langenv.task.reward`), each beside its compiled twin (``observation_kernels.py``,
``reward_kernels.py``)."""
