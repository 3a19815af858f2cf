//! The study's outputs for people: heat maps of a sweep (the paper's Figures 5 and 6), the
//! search's convergence (Figure 7), mounting tolerances, a side and top sketch of the rig with its view
//! frustums and the cell in 3D (a canvas view inlined with its scene), the verified poses' figures and precision–recall curves, `summary.csv`, and the self-contained `report.html`. Plots are written as SVG
//! and PNG with plotters through config's plot files; text needs a TrueType font found on the machine.

pub mod base64;
pub mod convergence;
pub mod heatmap;
pub mod html;
pub mod recommended;
pub mod rig_sketch;
pub mod study_report;
pub mod sweep_panels;
pub mod table;
pub mod tolerance_plot;
pub mod verification;
pub mod view3d;
