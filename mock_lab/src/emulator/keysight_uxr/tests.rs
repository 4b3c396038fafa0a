use super::*;

fn ask(scope: &KeysightUxr, text: &str) -> String {
    String::from_utf8_lossy(&scope.execute(text.as_bytes()).unwrap_or_default()).into_owned()
}

#[test]
fn identifies_and_keeps_an_error_queue() {
    let scope = KeysightUxr::embedded().unwrap();
    assert!(ask(&scope, "*IDN?").starts_with("MOCK_LAB,UXR0334A-EMU,"));
    assert_eq!(ask(&scope, ":SYST:ERR?"), "0,\"No error\"");
    ask(&scope, ":BOGUS 1");
    assert!(ask(&scope, ":SYSTem:ERRor?").starts_with("-113,"));
    ask(&scope, ":CHAN1:SCAL 7");
    assert!(ask(&scope, ":SYST:ERR?").starts_with("-222,"));
}

#[test]
fn a_single_acquisition_reads_back_as_word_blocks() {
    let scope = KeysightUxr::embedded().unwrap();
    for c in [
        ":SYST:HEAD OFF",
        ":WAV:FORM WORD",
        ":WAV:BYT LSBF",
        ":CHAN1:DISP ON",
        ":CHAN2:DISP ON",
        ":ACQ:MODE SEGM",
        ":ACQ:SEGM:COUN 3",
        ":WAV:SEGM:ALL ON",
        ":ACQ:SRAT:ANAL 128E9",
        ":ACQ:POIN:ANAL 1000",
        ":TRIG:EDGE:SOUR AUX",
        ":TRIG:LEV AUX,0.25",
    ] {
        ask(&scope, c);
    }
    assert_eq!(ask(&scope, ":SYST:ERR?"), "0,\"No error\"");
    assert_eq!(ask(&scope, ":ADER?"), "0");
    ask(&scope, ":SINGle");
    assert_eq!(ask(&scope, ":ADER?"), "1");
    assert_eq!(ask(&scope, ":ADER?"), "0", "reading clears the register");
    ask(&scope, ":WAV:SOUR CHAN2");
    let pre = ask(&scope, ":WAV:PRE?");
    let fields: Vec<&str> = pre.split(',').collect();
    assert_eq!(fields.len(), 24);
    assert_eq!(fields[0], "2");
    assert_eq!(fields[2], "1000");
    let data = scope.execute(b":WAV:DATA?").unwrap();
    assert!(data.starts_with(b"#46000"), "3 segments x 1000 words");
    assert_eq!(ask(&scope, ":WAV:SEGM:XLIS? TTAG").split(',').count(), 3);
}
