"""The contracts, the bottom layer: what plugins implement and use (the plugin API behind
``hnnbench``'s public names: systems and models, datasets, metrics, claims, search
spaces, kinematics, the reference integrator, model outputs, measured-data files, paths,
errors, devices) and the record's names every layer agrees on. It imports nothing else
of hnnbench (docs/ARCHITECTURE.md, "Layers").
"""
