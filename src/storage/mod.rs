//! Outputs: run folders, SigMF, npy/CSV, plots.
pub mod sigmf;
