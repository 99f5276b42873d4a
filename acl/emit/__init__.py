"""Schedules -> files: schedule.json (``schedule_json``), streamed waveforms (``render``,
``writers``), plots (``plot``), all written atomically by :func:`acl.emit.output.emit`."""
