//! The cell file: table, tray, items, sensor, placement, lighting, scenario ranges and the
//! estimator's settings. The built-in default cell is `default_cell.toml` (the text that
//! `camplace init` writes, a comment on every key); a user's file is laid over it key by
//! key, so a file names only what differs, and an unknown key is an error.

pub(crate) mod check;
pub(crate) mod load;
pub(crate) mod realism;
pub(crate) mod schema;
pub(crate) mod toml_merge;
pub(crate) mod trays;
pub(crate) mod values;

pub use check::{MAX_ITERATIONS, MAX_TEXTURE};
pub use load::DEFAULT_CELL_TOML;
pub use schema::{
    Cell, EstimatorParams, EstimatorPreset, Items, ItemsKind, Lighting, Metrics, PhaseParams, ReconstructionParams,
    Robot, Scenarios, Sensor, StereoParams, Table, Tray, TrayKind, WorkVolume,
};

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn default_is_the_papers_table_1() {
        let c = Cell::default();
        assert_eq!(c.estimator.surface_resolution, 2.0);
        assert_eq!(c.estimator.k, 25);
        assert_eq!(c.estimator.ransac_iterations, 100_000);
        assert_eq!(c.estimator.icp_iterations, 100);
    }

    #[test]
    fn every_key_of_the_template_has_a_comment() {
        let lines: Vec<&str> = DEFAULT_CELL_TOML.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            let t = line.trim();
            if t.is_empty() || t.starts_with('#') || t.starts_with('[') {
                continue;
            }
            assert!(i > 0 && lines[i - 1].trim_start().starts_with('#'), "key without a comment: {t}");
        }
    }

    #[test]
    fn values_that_mean_nothing_are_refused_naming_the_key() {
        let cases = [
            ("[table]\nsize = [1e308, 1e308]\n", "table.size"),
            ("[table]\nsize = [1e-300, 900.0]\n", "table.size"),
            ("[items]\nsize = [34.0, 34.0, 1e9]\n", "items.size"),
            ("[tray]\nmesh = \"tray.stl\"\n", "tray.mesh"),
            ("[tray]\nslots = [[0.0, 0.0, 0.0, 0.0]]\n", "tray.slots"),
            ("[items]\nmesh = \"item.stl\"\n", "items.mesh"),
            ("[tray]\nsymmetries = [-90.0]\n", "tray.symmetries[0]"),
            ("[tray]\nsymmetries = [180.0, 360.0]\n", "tray.symmetries[1]"),
            ("[tray]\nsymmetries = [1e-300]\n", "tray.symmetries[0]"),
            ("[tray]\nsymmetries = [0.123456789]\n", "tray.symmetries[0]"),
            ("[sensor]\nprojector_gain = 1e308\n", "sensor.projector_gain"),
            ("[placement]\nazimuth = 1e308\n", "placement.azimuth"),
            ("[lighting]\nlamp_distance = 1e-300\n", "lighting.lamp_distance"),
            ("[lighting]\nlamp_distance = 4294967296\n", "lighting.lamp_distance"),
            ("[work_volume]\nz = [0.0, 0.0]\n", "work_volume.z"),
            ("[stereo]\nspeckle_similarity = 1e308\n", "stereo.speckle_similarity"),
            ("[estimator]\nheight_band = 1e308\n", "estimator.height_band"),
            ("[estimator]\nicp_max_distance = 1e308\n", "estimator.icp_max_distance"),
            ("[estimator]\ninlier_distance = 4294967296\n", "estimator.inlier_distance"),
            ("[estimator]\nransac_sample = 0\n", "estimator.ransac_sample"),
            ("[estimator]\nransac_sample = 4\n", "estimator.ransac_sample"),
            ("[metrics]\nsuccess_rotation = 1e9\n", "metrics.success_rotation"),
            ("[stereo]\nlr_tolerance = 4294967296\n", "stereo.lr_tolerance"),
            ("[stereo]\nprior_sigma = 1e308\n", "stereo.prior_sigma"),
            ("[stereo]\nrow_step = 0\n", "stereo.row_step"),
            ("[stereo]\nrow_step = 9\n", "stereo.row_step"),
            ("[phase]\nmin_modulation = 1e9\n", "phase.min_modulation"),
            ("[reconstruction]\nbackground_margin = 1e308\n", "reconstruction.background_margin"),
        ];
        for (text, key) in cases {
            let e = Cell::from_toml_str(text, Path::new(".")).unwrap_err();
            assert!(e.to_string().starts_with(key), "{text}: {e}");
        }
        // Symmetries that are fractions of a turn are kept.
        let c =
            Cell::from_toml_str("[tray]\nsymmetries = [90.0, 180.0, 270.0, 120.0, 72.0]\n", Path::new(".")).unwrap();
        assert_eq!(c.tray.symmetries.len(), 5);
    }

    #[test]
    fn partial_file_lays_over_default() {
        let c = Cell::from_toml_str("[placement]\nr = 700\n", Path::new(".")).unwrap();
        assert_eq!(c.placement.r, 700.0);
        assert_eq!(c.placement.alpha, Cell::default().placement.alpha);
    }

    #[test]
    fn serialised_cell_reads_back() {
        let c = Cell::default();
        let back = Cell::from_toml_str(&c.to_toml_string(), Path::new(".")).unwrap();
        assert_eq!(back, c);
    }

    #[test]
    fn toml_syntax_errors_name_the_line_and_key() {
        let e =
            Cell::from_toml_str("[scenarios]\ncount = 4\n\n[stereo]\nmin_texture = = 3\n", Path::new(".")).unwrap_err();
        assert_eq!(e.key(), "stereo.min_texture", "{e}");
        assert!(e.to_string().contains("line 5"), "{e}");
        let e = Cell::from_toml_str("[stereo\nmin_texture = 3\n", Path::new(".")).unwrap_err();
        assert!(e.to_string().contains("line 1"), "{e}");
    }

    #[test]
    fn unknown_key_is_named() {
        let e = Cell::from_toml_str("[tray]\ncolour = 3\n", Path::new(".")).unwrap_err();
        assert_eq!(e.key(), "tray.colour", "{e}");
        assert!(e.message().contains("unknown key"), "{e}");
    }

    #[test]
    fn wrong_type_is_named() {
        let e = Cell::from_toml_str("[estimator]\nk = \"many\"\n", Path::new(".")).unwrap_err();
        assert_eq!(e.key(), "estimator.k", "{e}");
    }

    #[test]
    fn model_fill_states_out_of_range_are_named() {
        for bad in ["0", "1001", "-3", "2.5"] {
            let text = format!("[estimator]\nmodel_fill_states = {bad}\n");
            let e = Cell::from_toml_str(&text, Path::new(".")).unwrap_err();
            assert_eq!(e.key(), "estimator.model_fill_states", "{bad}: {e}");
        }
        for good in [1, 3, 1000] {
            let text = format!("[estimator]\nmodel_fill_states = {good}\n");
            assert_eq!(Cell::from_toml_str(&text, Path::new(".")).unwrap().estimator.model_fill_states, good);
        }
    }

    #[test]
    fn a_fragment_laid_over_a_cell_replaces_only_its_keys() {
        let mut own = Cell::default();
        own.sensor.camera_resolution = [320, 240];
        own.table.albedo = 0.3;
        let fitted = own
            .overlaid("[sensor]\nblur = 5\nnoise_amplitude = 17\n[lighting]\nambient = [0.1, 0.2]\n", Path::new("."))
            .unwrap();
        assert_eq!((fitted.sensor.blur, fitted.sensor.noise_amplitude), (5, 17));
        assert_eq!(fitted.lighting.ambient, [0.1, 0.2]);
        let mut want = own.clone();
        want.sensor.blur = 5;
        want.sensor.noise_amplitude = 17;
        want.lighting.ambient = [0.1, 0.2];
        assert_eq!(fitted, want);
        let bad = own.overlaid("[sensor]\nblur = 4\n", Path::new(".")).unwrap_err();
        assert!(bad.to_string().contains("sensor.blur"), "{bad}");
        assert!(own.overlaid("[sensor\n", Path::new(".")).is_err());
    }
}
