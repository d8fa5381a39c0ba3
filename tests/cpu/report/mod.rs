//! `report`: image metrics, plots and CSV.

mod metrics;
mod plot;
mod supersample;
