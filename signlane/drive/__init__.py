"""The transport-free drive stack and what surrounds it on a car: perception built once
(perception.py), the closed-loop stack (stack.py), camera and video sources, actuators, the
`signlane run` loop and the live web monitor. Nothing here knows of the VIA protocol."""
