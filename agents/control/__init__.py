"""Control: turning a planned path into thrust under the real dynamics and thrust limit (the MPC
tracker and the reference profiles it follows). Imports planners, never policies or experiments.
"""
