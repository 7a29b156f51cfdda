//! `haptics-server`: device backends, the servo loop and the transports.
