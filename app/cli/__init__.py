"""The ``isochor`` command and the editor's entry point.

- :mod:`.main`       ``isochor``: the editor, ``solve``, ``examples``; exit statuses, one-line
  errors (Qt only for the editor)
- :mod:`.sequence`   ``isochor solve --sequence``: the frames written all or none
- :mod:`.opening`    the session a command solves, and whether it loads the compiled kernels
- :mod:`.interrupts` Ctrl-C, SIGTERM, SIGHUP: one line, exit 128+signal, nothing written
- :mod:`.console`    exit statuses; standard output that a closed pipe silences; ending at once
  (`leave_now`)
- :mod:`.launch`     ``run_editor``: the display check (before any Qt import), the Qt
  application, screenshot mode
"""
