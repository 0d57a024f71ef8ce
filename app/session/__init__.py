"""The editing session: QObjects with no widgets, between the editor model and the window.

- :mod:`.controller`  EditorSession: document + undo stack + solve worker + frame scheduling
- :mod:`.drag`        SessionDrag, the session's part for drags and the live preview solves
  while one runs; DragHost, its interface to the session
- :mod:`.commands`    undo commands acting on the document
- :mod:`.worker`      SolveWorker: the core's solve generator on a background thread;
  records reach the GUI thread by queued signals
- :mod:`.framesolver` the timeline's frames solved in the background
- :mod:`.reader`      the child process that reads a big model and builds its pyramid
"""
