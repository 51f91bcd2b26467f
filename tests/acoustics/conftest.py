"""Room acoustics: the simulators' physics (delays, levels, decay, T30), HRTFs and the SOFA reader, rigid spheres, moving reflections.

Shared fixtures (the demo corpus, generated datasets by name, the in-process CLI) are
in tests/conftest.py; helpers in tests/support/."""
