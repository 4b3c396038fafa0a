//! Teledyne LeCroy LabMaster emulator.
