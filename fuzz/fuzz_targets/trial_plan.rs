//! A trial's `plan.json` (`camplace trial plan` writes it, a user may edit it): an error
//! naming the key or a checked plan, never a panic; what is accepted written back reads
//! back the same, and its robot table (`plan.csv`) is made without a panic.
#![no_main]

use camplace_config::TrialPlan;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(plan) = TrialPlan::from_json(text) else { return };
    let written = serde_json::to_string(&plan).expect("plain data");
    let back = TrialPlan::from_json(&written).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(back, plan);
    let _ = plan.csv();
});
