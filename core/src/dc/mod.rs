//! Distributed Clocks maths and state machine.
