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
        err.contains("ray.increment_frac_bits") && err.contains("1..=ray.position_frac_bits (12)"),
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
    // A denormal clock or step time would make the frame time zero and the frame rate
    // infinite (written as `"fps": null`): both have a lower bound (issue 17, item 12).
    for (field, value) in [
        ("clock.step_time_ns", "5e-324"),
        ("clock.frequency_mhz", "5e-324"),
        ("memory.host_link_mhz", "1e-300"),
    ] {
        let err = load(vizsim::config::DEFAULT_TOML, &[&format!("{field}={value}")])
            .unwrap_err()
            .to_string();
        assert!(err.contains(field) && err.contains("0.001..="), "{err}");
    }
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

/// A misspelt section in `--set` (or an experiment axis) lists the sections, as a misspelt
/// field lists the fields (it said only "no section `memroy`"); a field used as a section is
/// said to be one.
#[test]
fn a_misspelt_section_lists_the_sections() {
    let err = load(vizsim::config::DEFAULT_TOML, &["memroy.rows=16"])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("no section `memroy`; sections here: ")
            && err.contains(" memory, ")
            && err.contains(" sdram, "),
        "{err}"
    );
    let err = load(vizsim::config::DEFAULT_TOML, &["clock.step_time_ns.x=1"])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("`step_time_ns` is a field, not a section"),
        "{err}"
    );
}

/// A volume too large for the memory names the mapping as TOML spells it, not `Replicated4`.
#[test]
fn memory_messages_spell_the_mapping_as_toml_does() {
    let config = load(vizsim::config::DEFAULT_TOML, &["memory.rows=16"]).unwrap();
    let err = config
        .memory
        .check_covers([256, 256, 256], "test")
        .unwrap_err()
        .to_string();
    assert!(err.contains("with mapping replicated4,"), "{err}");
}

#[test]
fn malformed_toml_names_the_file() {
    let err = load("[ray\nposition_int_bits = 3", &[])
        .unwrap_err()
        .to_string();
    assert!(err.contains("test.toml"), "{err}");
}

#[test]
fn pipeline_and_memory_fields_are_validated() {
    for (set, field) in [
        ("ray_queue.rays=0", "ray_queue.rays"),
        ("skip.latency=0", "skip.latency"),
        (
            "compositing.buffer_capacity=0",
            "compositing.buffer_capacity",
        ),
        ("compositing.stage_latency=0", "compositing.stage_latency"),
        (
            "compositing.ert_feedback_latency=0",
            "compositing.ert_feedback_latency",
        ),
        ("clock.frequency_mhz=0.0", "clock.frequency_mhz"),
        ("memory.voxel_fifo_depth=0", "memory.voxel_fifo_depth"),
        ("memory.address_fifo_depth=0", "memory.address_fifo_depth"),
        ("memory.banks=3", "memory.banks"),
        ("sdram.t_rcd=0", "sdram.t_rcd"),
        ("sdram.refresh_interval=5", "sdram.refresh_interval"),
        // The default timing with 4 banks: a READ can wait 19 cycles behind a refresh.
        ("sdram.refresh_interval=18", "sdram.refresh_interval"),
    ] {
        let err = load(vizsim::config::DEFAULT_TOML, &[set])
            .unwrap_err()
            .to_string();
        assert!(err.contains(field), "{set}: {err}");
    }
}

#[test]
fn skip_policy_defaults_to_leap_only_and_rejects_other_values_naming_them() {
    use vizsim::config::SkipPolicy;
    let config = HardwareConfig::default_config();
    assert_eq!(config.skip.policy, SkipPolicy::LeapOnly);
    // A file written before the field existed still reads, with the default.
    let old = vizsim::config::DEFAULT_TOML.replace("policy = \"leap-only\"", "");
    assert_ne!(old, vizsim::config::DEFAULT_TOML);
    assert_eq!(load(&old, &[]).unwrap(), config);
    for set in [
        "skip.policy=sample-then-leap",
        "skip.policy=\"sample-then-leap\"",
    ] {
        let c = load(vizsim::config::DEFAULT_TOML, &[set]).unwrap();
        assert_eq!(c.skip.policy, SkipPolicy::SampleThenLeap, "{set}");
    }
    let text = vizsim::config::DEFAULT_TOML.replace("\"leap-only\"", "\"leap-always\"");
    for err in [
        load(&text, &[]).unwrap_err().to_string(),
        load(vizsim::config::DEFAULT_TOML, &["skip.policy=sample-only"])
            .unwrap_err()
            .to_string(),
    ] {
        assert!(
            err.contains("test.toml")
                && err.contains("skip.policy")
                && err.contains("leap-only")
                && err.contains("sample-then-leap"),
            "{err}"
        );
    }
}

/// Run keys hash the serialised configuration: the default policy is not written out, so every
/// existing result keeps its key; the other policy is, so its runs get keys of their own.
#[test]
fn skip_policy_is_serialised_only_when_not_the_default() {
    let config = HardwareConfig::default_config();
    let json = serde_json::to_value(&config).unwrap();
    assert!(json["skip"].get("policy").is_none(), "{}", json["skip"]);
    let other = load(
        vizsim::config::DEFAULT_TOML,
        &["skip.policy=sample-then-leap"],
    )
    .unwrap();
    let json = serde_json::to_value(&other).unwrap();
    assert_eq!(json["skip"]["policy"], "sample-then-leap");
    let back: HardwareConfig = serde_json::from_value(json).unwrap();
    assert_eq!(back, other);
}
