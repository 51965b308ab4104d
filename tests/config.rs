use vizsim::config::HardwareConfig;

fn load(text: &str, overrides: &[&str]) -> vizsim::Result<HardwareConfig> {
    let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    HardwareConfig::from_toml_str(text, "test.toml", &overrides)
}

#[test]
fn the_shipped_file_is_the_embedded_default() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/configs/hardware/vizard2.toml"
    ))
    .unwrap();
    let config = load(&text, &[]).unwrap();
    assert_eq!(config, HardwareConfig::default_config());
    assert_eq!(config.occupancy.sram_bits, 131072);
    assert_eq!(config.clock.step_time_ns, 12.5);
}

#[test]
fn unknown_field_is_an_error_naming_it() {
    let text = vizsim::config::DEFAULT_TOML.replace("[skip]", "[skip]\nrecipocal_bits = 3");
    let err = load(&text, &[]).unwrap_err().to_string();
    assert!(
        err.contains("test.toml") && err.contains("recipocal_bits"),
        "{err}"
    );
}

#[test]
fn out_of_range_values_name_field_and_range() {
    let err = load(vizsim::config::DEFAULT_TOML, &["skip.reciprocal_bits=1"])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("skip.reciprocal_bits") && err.contains("2..=32"),
        "{err}"
    );
    let err = load(
        vizsim::config::DEFAULT_TOML,
        &["ray.increment_frac_bits=13"],
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("ray.increment_frac_bits") && err.contains("1..=12"),
        "{err}"
    );
    let err = load(vizsim::config::DEFAULT_TOML, &["occupancy.subcube=12"])
        .unwrap_err()
        .to_string();
    assert!(err.contains("occupancy.subcube"), "{err}");
    let err = load(
        vizsim::config::DEFAULT_TOML,
        &["compositing.ert_threshold=1.5"],
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("compositing.ert_threshold"), "{err}");
}

#[test]
fn set_overrides_apply_and_are_validated_like_the_file() {
    let config = load(
        vizsim::config::DEFAULT_TOML,
        &[
            "skip.reciprocal_bits=6",
            "occupancy.kind=zero",
            "occupancy.hierarchy=true",
        ],
    )
    .unwrap();
    assert_eq!(config.skip.reciprocal_bits, 6);
    assert!(config.occupancy.hierarchy);
    let err = load(vizsim::config::DEFAULT_TOML, &["skip.nonesuch=3"])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("nonesuch") && err.contains("reciprocal_bits"),
        "{err}"
    );
    let err = load(vizsim::config::DEFAULT_TOML, &["skip.reciprocal_bits=many"])
        .unwrap_err()
        .to_string();
    assert!(err.contains("reciprocal_bits"), "{err}");
    let err = load(vizsim::config::DEFAULT_TOML, &["noequals"])
        .unwrap_err()
        .to_string();
    assert!(err.contains("--set"), "{err}");
}

#[test]
fn malformed_toml_names_the_file() {
    let err = load("[ray\nposition_int_bits = 3", &[])
        .unwrap_err()
        .to_string();
    assert!(err.contains("test.toml"), "{err}");
}
