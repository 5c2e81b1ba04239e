"""Training scripts of LangCtrl: ``python -m train.ppo`` (the learned aligner) and its wrappers."""
