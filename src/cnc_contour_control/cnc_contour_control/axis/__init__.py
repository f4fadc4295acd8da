"""The axis loop: the servo (a law on one axis), hold, safety latches and the spindle."""
