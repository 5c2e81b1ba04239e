"""Live mode: the environment in real time, with you as the person and the robot's voice aloud.

``langctrl play`` composes these parts (each a class with one job):

* :mod:`langenv.live.registry`: policies by name, from the ``langctrl.policies`` entry points
  (langenv itself never imports a policy package);
* :mod:`langenv.live.ring`: the audio buffer between the loop and the sound card;
* :mod:`langenv.live.stream`: the speech timeline played through the block phase vocoder at the
  audio pace, a fixed lag behind the simulation;
* :mod:`langenv.live.sinks`: where the audio goes: the sound card (sounddevice, loaded lazily) or
  a WAV file fed at the sound card's pace (headless);
* :mod:`langenv.live.drag`: the person as the viewer's mouse perturbation;
* :mod:`langenv.live.loop`: the real-time loop: env steps on the wall clock, audio, statistics;
* :mod:`langenv.live.viewer`: MuJoCo's interactive viewer with the paces and the phrase shown.
"""
