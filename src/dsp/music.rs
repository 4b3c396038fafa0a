//! MUSIC super-resolution (spatial smoothing, forward-backward, MDL/AIC) and a grid-free estimator.
