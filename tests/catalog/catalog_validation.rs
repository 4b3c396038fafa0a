//! The instrument catalog: every shipped file loads and validates; bad files are refused with the
//! file, the field, the line and the reason; a folder overrides the built-in files.

use radbench::catalog::{
    parse_model, Catalog, CatalogError, InstrumentKind, Problem, TransportKind, EMBEDDED_FILES,
};
use radbench::exit::{Classify, ExitClass};

fn embedded(name: &str) -> &'static str {
    EMBEDDED_FILES
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, text)| *text)
        .expect("embedded file exists")
}

/// Replaces exactly one occurrence of `from` in `text` (the test fails if the anchor moved).
fn mutate(text: &str, from: &str, to: &str) -> String {
    assert_eq!(
        text.matches(from).count(),
        1,
        "anchor {from:?} must occur once"
    );
    text.replacen(from, to, 1)
}

fn line_of(text: &str, needle: &str) -> usize {
    let at = text.find(needle).expect("needle in text");
    text[..at].matches('\n').count() + 1
}

fn problems(result: Result<radbench::catalog::InstrumentModel, CatalogError>) -> Vec<Problem> {
    match result {
        Err(CatalogError::Invalid { problems, .. }) => problems,
        other => panic!("expected an invalid-file error, got {other:?}"),
    }
}

#[test]
fn every_shipped_file_loads_and_validates() {
    let catalog = Catalog::embedded().unwrap();
    let keys: Vec<_> = catalog
        .models()
        .map(|(m, _)| m.instrument.key.clone())
        .collect();
    assert_eq!(
        keys,
        [
            "keysight-m8195a",
            "lecroy-labmaster10zi-a",
            "gotmic-eband-tx",
            "gotmic-eband-rx",
            "keysight-uxr0334a"
        ]
    );
    let awg = catalog.get("keysight-m8195a").unwrap();
    assert_eq!(awg.instrument.kind, InstrumentKind::Awg);
    let limits = awg.awg.as_ref().unwrap();
    assert_eq!(limits.divider(4).unwrap().granularity, 64);
    assert_eq!(limits.divider(1).unwrap().min_segment_samples, 1280);
    assert_eq!(limits.dac_rate_min, 53.76e9);
    assert_eq!(limits.dac_mode("dcmarker").unwrap().marker_channels, [3, 4]);
    let scope = catalog.get("lecroy-labmaster10zi-a").unwrap();
    assert_eq!(scope.digitizer.as_ref().unwrap().sample_rates, [80e9]);
    assert_eq!(scope.transports[0].kind, TransportKind::Vicp);
    assert_eq!(
        scope.transports[0].resource_for("10.0.0.5"),
        "VICP::10.0.0.5::INSTR"
    );
    let tx = catalog.get("gotmic-eband-tx").unwrap();
    assert!(tx.rf.as_ref().unwrap().enable_requires_interlock_closed);
    let control = tx.registers.iter().find(|r| r.name == "CONTROL").unwrap();
    assert_eq!(control.address, 0x02);
    assert_eq!(control.bit("AMP_ENABLE"), Some(1));
}

#[test]
fn identify_recognises_vendors_and_emulators() {
    let catalog = Catalog::embedded().unwrap();
    let hit = catalog
        .identify("Keysight Technologies,M8195A,MY12345,4.1.0.0\n")
        .unwrap();
    assert_eq!(hit.model.instrument.key, "keysight-m8195a");
    assert!(!hit.emulated);
    let hit = catalog
        .identify("LECROY,LABMASTER10-36ZI-A,LCRY1234,9.4.0")
        .unwrap();
    assert_eq!(hit.model.instrument.key, "lecroy-labmaster10zi-a");
    let hit = catalog
        .identify("MOCK_LAB,GOTMIC-EBAND-RX-EMU,EMU0004,mock_lab-1")
        .unwrap();
    assert_eq!(hit.model.instrument.key, "gotmic-eband-rx");
    assert!(hit.emulated);
    assert!(catalog.identify("Rigol,DS1054Z,x,y").is_none());
}

#[test]
fn timeouts_grow_with_transfer_size() {
    let catalog = Catalog::embedded().unwrap();
    let t = catalog.get("keysight-m8195a").unwrap().timeouts;
    assert_eq!(t.for_transfer(t.write_ms, 0).as_millis(), 10_000);
    assert_eq!(t.for_transfer(t.write_ms, 2_000_000).as_millis(), 11_000);
}

#[test]
fn type_error_names_file_field_and_line() {
    let text = mutate(
        embedded("keysight_m8195a.toml"),
        "channels = 4",
        "channels = \"four\"",
    );
    let err = parse_model("bad_type.toml", &text).unwrap_err();
    let message = err.to_string();
    assert!(message.contains("bad_type.toml"), "{message}");
    let p = &err.problems()[0];
    assert_eq!(p.field, "awg.channels");
    assert_eq!(p.line, Some(line_of(&text, "channels = \"four\"")));
    assert!(p.reason.contains("invalid type"), "{}", p.reason);
    assert_eq!(err.exit_class(), ExitClass::BadInput);
}

#[test]
fn unknown_field_is_refused_not_ignored() {
    let text = mutate(
        embedded("keysight_m8195a.toml"),
        "sample_bits = 8",
        "sample_bits = 8\nsampel_rate = 3",
    );
    let p = &problems(parse_model("typo.toml", &text))[0];
    assert!(
        p.reason.contains("unknown field `sampel_rate`"),
        "{}",
        p.reason
    );
    assert_eq!(p.line, Some(line_of(&text, "sampel_rate")));
}

#[test]
fn missing_field_is_named() {
    let text = mutate(
        embedded("lecroy_labmaster10zi_a.toml"),
        "adc_bits = 8\n",
        "",
    );
    let p = &problems(parse_model("missing.toml", &text))[0];
    assert!(
        p.reason.contains("missing field `adc_bits`"),
        "{}",
        p.reason
    );
    assert!(p.line.is_some());
}

#[test]
fn toml_syntax_error_gives_the_line() {
    let text = mutate(
        embedded("gotmic_eband_tx.toml"),
        "baud = 115200",
        "baud = = 115200",
    );
    let p = &problems(parse_model("syntax.toml", &text))[0];
    assert_eq!(p.line, Some(line_of(&text, "baud = = 115200")));
}

#[test]
fn semantic_errors_name_field_line_and_what_is_allowed() {
    let text = mutate(
        embedded("keysight_m8195a.toml"),
        "granularity = 128\nmin_segment_samples = 640",
        "granularity = 128\nmin_segment_samples = 600",
    );
    let ps = problems(parse_model("granularity.toml", &text));
    assert_eq!(ps.len(), 1, "{ps:?}");
    assert_eq!(ps[0].field, "awg.divider[1].min_segment_samples");
    assert_eq!(
        ps[0].line,
        Some(line_of(&text, "min_segment_samples = 600"))
    );
    assert!(ps[0].reason.contains("multiple of the granularity 128"));

    let text = mutate(
        embedded("keysight_m8195a.toml"),
        "dac_rate_max = 65.0e9",
        "dac_rate_max = 50.0e9",
    );
    let ps = problems(parse_model("rates.toml", &text));
    let fields: Vec<_> = ps.iter().map(|p| p.field.as_str()).collect();
    assert!(fields.contains(&"awg.dac_rate_max"), "{fields:?}");
    assert!(fields.contains(&"awg.dac_rate_default"), "{fields:?}");
}

#[test]
fn several_problems_are_all_reported() {
    let text = mutate(
        embedded("lecroy_labmaster10zi_a.toml"),
        "ext_trigger_level_v_max = 0.5",
        "ext_trigger_level_v_max = -0.6",
    );
    let text = mutate(
        &text,
        "volts_per_div_default = 0.05",
        "volts_per_div_default = 5.0",
    );
    let text = mutate(&text, "port = 1861", "port = 0");
    let ps = problems(parse_model("scope.toml", &text));
    let fields: Vec<_> = ps.iter().map(|p| p.field.as_str()).collect();
    assert_eq!(
        fields,
        [
            "transport[0].port",
            "digitizer.volts_per_div_default",
            "digitizer.ext_trigger_level_v_max"
        ]
    );
    assert!(ps.iter().all(|p| p.line.is_some()));
}

/// The shipped LeCroy file with its `[vendor]` WAVEDESC fields also (or only) under
/// `[digitizer]`, their old place: `(template, bytes)` written there.
fn lecroy_old_place(keep_vendor: bool, bytes: u32) -> String {
    let mut text = embedded("lecroy_labmaster10zi_a.toml").to_string();
    if !keep_vendor {
        text = mutate(&text, "wavedesc_template = \"LECROY_2_3\"\n", "");
        text = mutate(&text, "wavedesc_bytes = 346\n", "");
    }
    mutate(
        &text,
        "[digitizer]\n",
        &format!("[digitizer]\nwavedesc_template = \"LECROY_2_3\"\nwavedesc_bytes = {bytes}\n"),
    )
}

#[test]
fn lecroy_wavedesc_fields_load_from_the_vendor_table_or_their_old_place() {
    let new = parse_model("new.toml", embedded("lecroy_labmaster10zi_a.toml")).unwrap();
    assert_eq!(new.vendor["wavedesc_template"].as_str(), Some("LECROY_2_3"));
    assert_eq!(new.vendor["wavedesc_bytes"].as_integer(), Some(346));
    // A file written for the radbench before the [vendor] table: the same model.
    let old = parse_model("old.toml", &lecroy_old_place(false, 346)).unwrap();
    assert_eq!(old.vendor, new.vendor);
    // Both places with the same value: accepted.
    let both = parse_model("both.toml", &lecroy_old_place(true, 346)).unwrap();
    assert_eq!(both.vendor, new.vendor);
}

#[test]
fn lecroy_wavedesc_fields_in_both_places_with_different_values_are_refused_naming_both() {
    let text = lecroy_old_place(true, 320);
    let ps = problems(parse_model("both.toml", &text));
    assert_eq!(ps.len(), 1, "{ps:?}");
    assert_eq!(ps[0].field, "digitizer.wavedesc_bytes");
    assert_eq!(ps[0].line, Some(line_of(&text, "wavedesc_bytes = 320")));
    assert!(
        ps[0].reason.contains("vendor.wavedesc_bytes")
            && ps[0].reason.contains("346")
            && ps[0].reason.contains("320")
            && ps[0].reason.contains("old place"),
        "{}",
        ps[0].reason
    );
}

#[test]
fn register_map_rules() {
    let tx = embedded("gotmic_eband_tx.toml");
    let text = mutate(tx, "address = 0x07", "address = 0x06");
    let ps = problems(parse_model("regs.toml", &text));
    assert_eq!(ps[0].field, "register[7].address");
    assert!(ps[0].reason.contains("0x06 is used twice"));

    let text = mutate(
        tx,
        "{ name = \"AMP_ENABLE\", bit = 1 }",
        "{ name = \"AMP_ON\", bit = 1 }",
    );
    let ps = problems(parse_model("fields.toml", &text));
    assert!(ps[0].reason.contains("AMP_ENABLE"), "{ps:?}");

    let text = mutate(tx, "reset = 63", "reset = 64");
    let ps = problems(parse_model("reset.toml", &text));
    assert_eq!(ps[0].field, "register[3].reset");
    assert_eq!(ps[0].line, Some(line_of(&text, "reset = 64")));
}

#[test]
fn emulator_may_not_claim_to_be_the_vendor() {
    let text = mutate(
        embedded("keysight_m8195a.toml"),
        "manufacturer = \"MOCK_LAB\"",
        "manufacturer = \"Keysight Technologies\"",
    );
    let ps = problems(parse_model("liar.toml", &text));
    assert_eq!(ps[0].field, "identity.emulator.manufacturer");
}

#[test]
fn kind_needs_its_section() {
    let text = mutate(
        embedded("keysight_m8195a.toml"),
        "kind = \"awg\"",
        "kind = \"digitizer\"",
    );
    let ps = problems(parse_model("kind.toml", &text));
    let fields: Vec<_> = ps.iter().map(|p| p.field.as_str()).collect();
    assert_eq!(fields, ["awg", "digitizer"]);
}

#[test]
fn folder_overrides_and_extends_the_built_in_files() {
    let dir = tempfile::tempdir().unwrap();
    let text = mutate(
        embedded("keysight_m8195a.toml"),
        "read_ms = 10000",
        "read_ms = 20000",
    );
    std::fs::write(dir.path().join("my_awg.toml"), text).unwrap();
    let extra = mutate(
        embedded("gotmic_eband_rx.toml"),
        "key = \"gotmic-eband-rx\"",
        "key = \"gotmic-eband-rx2\"",
    );
    std::fs::write(dir.path().join("second_rx.toml"), extra).unwrap();
    std::fs::write(dir.path().join("notes.txt"), "ignored").unwrap();

    let catalog = Catalog::load(Some(dir.path())).unwrap();
    assert_eq!(
        catalog.get("keysight-m8195a").unwrap().timeouts.read_ms,
        20_000
    );
    assert!(catalog.get("gotmic-eband-rx2").is_ok());
    assert_eq!(catalog.models().count(), EMBEDDED_FILES.len() + 1);
    let origin = catalog
        .models()
        .find(|(m, _)| m.instrument.key == "keysight-m8195a")
        .unwrap()
        .1
        .to_string();
    assert!(origin.ends_with("my_awg.toml"), "{origin}");
}

#[test]
fn bad_override_file_is_named_by_its_path() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.toml");
    std::fs::write(&path, "schema = 2\n").unwrap();
    let err = Catalog::load(Some(dir.path())).unwrap_err();
    assert!(
        err.to_string().contains(&path.display().to_string()),
        "{err}"
    );
}

#[test]
fn duplicate_keys_in_a_folder_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("a.toml"), embedded("gotmic_eband_tx.toml")).unwrap();
    std::fs::write(dir.path().join("b.toml"), embedded("gotmic_eband_tx.toml")).unwrap();
    let err = Catalog::load(Some(dir.path())).unwrap_err();
    assert!(matches!(err, CatalogError::DuplicateKey { .. }), "{err}");
    let empty = tempfile::tempdir().unwrap();
    assert!(matches!(
        Catalog::load(Some(empty.path())),
        Err(CatalogError::EmptyDir { .. })
    ));
    assert!(matches!(
        Catalog::load(Some(&empty.path().join("nope"))),
        Err(CatalogError::ReadDir { .. })
    ));
}

#[test]
fn unknown_key_lists_the_known_ones() {
    let catalog = Catalog::embedded().unwrap();
    let err = catalog.get("tektronix-awg70k").unwrap_err();
    assert!(err.to_string().contains("keysight-m8195a"), "{err}");
}

#[test]
fn a_malformed_line_protocol_is_refused_with_the_key_and_what_is_allowed() {
    let tx = embedded("gotmic_eband_tx.toml");
    let cases = [
        (
            "write = \"W {address} {value}\"",
            "write = \"W {address}\"",
            "protocol.write",
            "must hold {value} once",
        ),
        (
            "read = \"R {address}\"",
            "read = \"R {address} {value}\"",
            "protocol.read",
            "holds {value}",
        ),
        (
            "reply_error = \"ERR\"",
            "reply_error = \"OK!\"",
            "protocol.reply_error",
            "must not start alike",
        ),
        (
            "crc_poly = 0x07",
            "crc_poly = 0x00",
            "protocol.crc_poly",
            "checksum = \"none\"",
        ),
    ];
    for (from, to, field, reason) in cases {
        let ps = problems(parse_model("proto.toml", &mutate(tx, from, to)));
        assert!(
            ps.iter()
                .any(|p| p.field == field && p.reason.contains(reason)),
            "{to}: {ps:?}"
        );
    }
    // An unknown checksum kind names the key and the kinds there are.
    let err = parse_model(
        "proto.toml",
        &mutate(tx, "checksum = \"crc8\"", "checksum = \"crc16\""),
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("checksum") && err.contains("crc8") && err.contains("none"),
        "{err}"
    );
    // Another protocol, described with every key, loads.
    let fixture = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/protocols/acme_eband_tx.toml"),
    )
    .unwrap();
    parse_model("acme_eband_tx.toml", &fixture).unwrap();
}
