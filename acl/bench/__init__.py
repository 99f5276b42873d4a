"""The bench: play a compiled schedule on a signal generator (SCPI over PyVISA) and track video.

``acl play`` (acl/commands/play.py) and ``acl track`` (acl/commands/track.py) are thin; the work is
here: :mod:`acl.bench.chain` (generator and amplifier datasheet values), :mod:`acl.bench.schedule`
(reading schedule.json), :mod:`acl.bench.plan` (the SCPI command stream of a dialect),
:mod:`acl.bench.player` (sending it, reading every setting back) and :mod:`acl.bench.track`
(sub-pixel registration of a microscope video).  docs/bench.md.
"""
