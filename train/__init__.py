"""Training scripts of LangCtrl: ``langctrl train`` (the learned aligner) and its wrappers."""
