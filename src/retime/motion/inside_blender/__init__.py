"""Code that runs inside Blender's Python (bpy, mathutils and NumPy only), never imported by retime itself.

* :mod:`.armature` turns an armature's animation into BVH-convention arrays and BVH text, and
  BVH-convention poses back into keys; the Blender add-on ships a copy of it (``blender/build.py``).
* :mod:`.bridge` is the script that retime runs in a Python with ``bpy`` (or in ``blender
  --background``) to read and write FBX and glTF files (see :mod:`retime.motion.blender_io`).
"""
