"""The jobs a user runs, built from the areas below: :mod:`.reconstruct` (frames to a model, trajectory and report),
:mod:`.pick` (scan, find the parts, plan grasps and joint targets) and :mod:`.batch` (many jobs on a process pool or
Ray). Each takes its C++ settings struct (``ReconstructionSettings``, ``PickSettings``) and dumps it beside its result.
"""
