"""MuBlE's files: scene and instruction files, the dataset's layout, manifests, keyframe states, contact sheets,
atomic writes, and the primitive names of the original release's sequence files."""
