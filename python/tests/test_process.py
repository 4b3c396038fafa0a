"""radbench.process equals `radbench process`'s summary.json; read_capture, the waveforms and
the errors."""

import numpy as np
import pytest

import radbench
from conftest import cli_process


def without_files(summary):
    return {k: v for k, v in summary.items() if k != "files"}


@pytest.mark.parametrize(
    "name, options, kwargs",
    [
        ("msk-lfm", [], {}),
        ("ofdm", [], {}),
        ("music", [], {}),
        ("ofdm", ["--algorithm", "music", "--m", "48", "--p", "1"], {"algorithm": "music", "m": 48, "p": 1}),
        ("msk-lfm", ["--window", "hann", "--min-range", "0.3"], {"window": "hann", "min_range": 0.3}),
    ],
)
def test_process_equals_the_command_lines_summary(archive, name, options, kwargs):
    folder = archive[name]
    [cli] = cli_process([folder], *options).values()
    py = radbench.process(str(folder), **kwargs)
    # Every key of summary.json but `files`: targets, widths, side-lobes, SNR, payload, options.
    assert py.summary == without_files(cli)
    assert py.targets == cli["targets"] and py.targets
    assert py.width_3db_cm == cli["width_3db_cm"]
    assert py.sidelobe_db == cli["sidelobe_db"]
    assert py.payload == cli["payload"]
    assert py.options == cli["processing"]
    assert py.algorithm == cli["algorithm"]


def test_music_separates_the_two_targets_of_the_scene(archive):
    r = radbench.process(archive["music"])
    assert r.algorithm == "music"
    truth = [t["range_m"] for t in r.summary["scene"]["targets"]]
    assert len(r.ranges_m) == 2
    for found, true in zip(r.ranges_m, truth):
        assert abs(found - true) < 0.01
    # The pseudo-spectrum and its Fourier overlay come along as arrays.
    assert len(r.profiles) >= 1 and r.profile.range_m.shape == r.profile.amplitude.shape


def test_arrays_match_the_profile_files(archive):
    folder = archive["msk-lfm"]
    r = radbench.process(folder)
    table = np.load(folder / "profile.npy")
    np.testing.assert_allclose(r.profile.range_m, table[:, 0], rtol=1e-12, atol=1e-12)
    assert r.threshold.shape == r.profile.amplitude.shape
    peak = r.profile.range_m[np.argmax(r.profile.amplitude)]
    assert abs(peak - r.ranges_m[0]) < 0.01
    assert r.payload["text"] == "from python" and r.payload["bit_errors"] == 0
    assert r.aligned.dtype == np.complex128


def test_read_capture_gives_raw_and_decimated_iq_metadata_and_truth(archive):
    c = radbench.read_capture(archive["msk-lfm"])
    assert c.iq.dtype == np.complex128 and c.iq.shape[0] == 1
    assert c.capture_rate_hz == 80e9 and c.processing_rate_hz == 16e9
    assert c.decimated.shape[1] * 5 <= c.iq.shape[1]
    assert c.metadata["global"]["core:sample_rate"] == 80e9
    assert c.radbench["waveform"] == c.metadata["global"]["radbench:waveform"]
    assert c.true_ranges_m == [1.0]
    # The .sigmf-meta names the same capture.
    again = radbench.read_capture(next(archive["msk-lfm"].glob("*.sigmf-meta")))
    np.testing.assert_array_equal(again.iq, c.iq)


def test_samples_go_through_the_same_pipeline(archive):
    c = radbench.read_capture(archive["msk-lfm"])
    r = radbench.process(c.iq[0], waveform="msk-lfm", capture_rate=c.capture_rate_hz,
                         trigger_offset=float(c.iq_t0_s[0]), payload="from python",
                         system_delay=c.radbench["system_delay_s"])
    saved = radbench.process(c)
    assert abs(r.ranges_m[0] - saved.ranges_m[0]) < 1e-6
    assert r.payload["bit_errors"] == 0


def test_waveforms_are_the_ones_capture_sends(archive):
    c = radbench.read_capture(archive["ofdm"])
    w = radbench.waveform.ofdm()
    assert w.description == c.radbench["waveform"]
    m = radbench.waveform.msk_lfm(bandwidth=2e9, payload="hi")
    assert m.i.dtype == np.int8 and len(m.i) == len(m.q) == len(m.samples)
    assert m.bandwidth_hz == 2e9 and m.payload == b"hi"
    assert m.marker()[: m.marker_high_samples].all()


def test_errors_carry_radbench_messages_and_exit_codes(archive, tmp_path):
    with pytest.raises(radbench.InputError, match="unknown keyword `zero_padd`; did you mean `zero_pad`") as e:
        radbench.process(archive["msk-lfm"], zero_padd=3)
    assert e.value.exit_code == 2 and isinstance(e.value, ValueError)
    # Errors name the Python keyword, never the command line's `--option`.
    with pytest.raises(radbench.InputError, match="unknown keyword `windw`; did you mean `window`") as e:
        radbench.process(archive["msk-lfm"], windw="hann")
    assert "--" not in str(e.value)
    with pytest.raises(radbench.InputError, match="window") as e:
        radbench.process(archive["msk-lfm"], window="hanning")
    assert "--window" not in str(e.value)
    with pytest.raises(radbench.InputError, match="algorithm"):
        radbench.process(archive["msk-lfm"], algorithm="bogus")
    with pytest.raises(radbench.RadbenchError, match="music"):
        radbench.process(archive["msk-lfm"], algorithm="music")
    with pytest.raises(radbench.InputError, match=str(tmp_path / "none")):
        radbench.read_capture(tmp_path / "none")
    with pytest.raises(radbench.InputError, match="bandwidth"):
        radbench.waveform.msk_lfm(bandwidth=-1.0)
    with pytest.raises(radbench.InputError, match="waveform"):
        radbench.process(np.zeros(100, complex), capture_rate=16e9)
