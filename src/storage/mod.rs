//! Outputs: run folders, SigMF, npy/CSV, plots.
