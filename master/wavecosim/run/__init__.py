"""One run: the runner that steps a master over a scene, the observers of each step, the recorder of
its rows and files, and its metadata."""
