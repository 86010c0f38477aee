"""Bounds of guided's search that its options must respect, kept apart from the compiled kernels so
that the command line, the editor and :class:`retime.guided.method.Settings` name them without
loading numba."""
import numpy as np

#: dtype of the dynamic program's back-pointers (:mod:`retime.guided.dp`): each holds the step, in
#: grid frames, from the previous output frame
BACK_POINTER = np.uint8
#: the largest skip limit (``--max-skip``) a back-pointer can hold
MAX_SKIP_LIMIT = int(np.iinfo(BACK_POINTER).max)
