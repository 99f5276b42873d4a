"""Program goals -> convex programs -> a schedule of tones (see docs/schedule.md).

Entry point: :func:`acl.schedule.compile.compile_program`.  Modules: ``model`` (the Schedule),
``path`` (path following, one QP), ``latch`` (switching LP), ``hold`` (snap-in LP), ``tones``
(tone choice), ``phases`` (crest factor), ``calibration`` (measured sweep CSV), ``gains``
(adapters to the analysis stage), ``solve`` (solver policy).  cvxpy is imported lazily.
"""
