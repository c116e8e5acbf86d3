"""The plumbing a reader need not see first: how files and folders of results are written (``atomic``:
atomic writes, ``outputs``: where a command may write, ``lock``: one writer per folder), how names from
outside are shown and used (``names``), how signals and standard streams are handled (``signals``,
``stdio``). The concepts live at the package root and in the layer folders; they use these."""
