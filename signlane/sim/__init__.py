"""Driving: the VIA protocol, the drive server, the local simulator and its score."""
