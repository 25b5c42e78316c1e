//! Servo specification: seed formulas and bounds for the clock servos (owned by the servo area).
