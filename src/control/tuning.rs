//! Gain tuning with the project's optimizers (to come).
