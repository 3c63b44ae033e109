"""The fleet run: simulation tasks on an engine, the outputs folder and unattended batch runs."""
