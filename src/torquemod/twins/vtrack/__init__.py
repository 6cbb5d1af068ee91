"""The V-Track rig twin: parameters, dynamics, theory, the simulation."""
