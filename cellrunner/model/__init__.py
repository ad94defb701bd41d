"""Pure data: cell and task models, units, the robot table. No I/O beyond file loading."""
