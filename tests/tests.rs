//! camplace's end-to-end tests: the CLI and the crates together, in one test binary.

mod budgets;
mod calibrate;
mod camplace_cmd;
mod capture;
mod cli_errors;
mod closed_output;
mod cluster;
mod commissioning;
mod data_safety;
mod deploy;
mod estimate;
mod hand_eye;
mod installed_rig;
mod integrity;
mod key_checks;
mod meshes;
mod own_cell;
mod placement;
mod reconstruct;
mod reconstruct_errors;
mod serve;
mod study;
mod study_folder;
mod tolerance;
mod trial;
mod verify;
