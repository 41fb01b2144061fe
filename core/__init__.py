"""Sampling Lab's renderer: NumPy + Embree (embreex). Never imports bpy."""
