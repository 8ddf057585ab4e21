"""The C++ source files under some top folders of the repository, for the tree checks
(check_layers.py, check_function_length.py)."""

import os

SOURCE_EXTS = (".h", ".hh", ".hpp", ".hxx", ".inl", ".ipp", ".c", ".cc", ".cpp", ".cxx")


def source_files(root, tops):
    """Yields (full path, path relative to root with '/') of every source file under each of
    `tops` in `root`, in sorted order (the same on every machine)."""
    for top in tops:
        for dirpath, dirnames, filenames in os.walk(os.path.join(root, top)):
            dirnames.sort()
            for fn in sorted(filenames):
                if fn.endswith(SOURCE_EXTS):
                    full = os.path.join(dirpath, fn)
                    yield full, os.path.relpath(full, root).replace(os.sep, "/")
