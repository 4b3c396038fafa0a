//! Issue 22's reproducibility target: a second `radbench calibrate response` on the same bench
//! (the `thesis-lab` chain, another noise realisation) reproduces the response within 0.2 dB and
//! 2 degrees across the band.

use super::support::radbench_in;
use std::path::Path;

/// The reference scene: one pillar at 1 m on the `thesis-lab` chain, noise seeded with `seed`.
fn scene(dir: &Path, seed: u64) -> String {
    let file = format!("reference-{seed}.toml");
    std::fs::write(
        dir.join(&file),
        format!(
            "seed = {seed}\nsnr_db = 25.0\n[[targets]]\nrange_m = 1.0\namplitude = 0.5\n\
             [chain]\npreset = \"thesis-lab\"\n"
        ),
    )
    .unwrap();
    file
}

/// The `.npy` table (float64, C order, 7 columns) as rows.
fn npy_rows(path: &Path) -> Vec<[f64; 7]> {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[..6], b"\x93NUMPY", "{}", path.display());
    let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = std::str::from_utf8(&bytes[10..10 + len]).unwrap();
    assert!(
        header.contains("'<f8'") && header.contains(", 7)"),
        "{header}"
    );
    let values: Vec<f64> = bytes[10 + len..]
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect();
    values
        .chunks_exact(7)
        .map(|r| r.try_into().unwrap())
        .collect()
}

/// Calibrates on the scene seeded with `seed`; the table's rows.
async fn calibrate(dir: &Path, seed: u64) -> Vec<[f64; 7]> {
    let reference = scene(dir, seed);
    let out = format!("response-{seed}.toml");
    let (code, _, err) = radbench_in(
        Some(dir),
        &[
            "calibrate",
            "response",
            "--reference-range",
            "1.0",
            "--scene",
            &reference,
            "--allow-rf",
            "--out",
            &out,
            "--json",
        ],
    )
    .await;
    assert_eq!(code, 0, "seed {seed}: {err}");
    npy_rows(&dir.join(format!("response-{seed}.npy")))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_second_calibration_with_other_noise_reproduces_the_response() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let first = calibrate(d, 11).await;
    let second = calibrate(d, 12).await;
    assert_eq!(first.len(), second.len(), "the same band, the same rows");
    let band: Vec<(&[f64; 7], &[f64; 7])> = first
        .iter()
        .zip(&second)
        .filter(|(a, _)| a[0].abs() <= 0.45e9)
        .collect();
    assert!(band.len() > 100, "{} rows in the band", band.len());
    let mut noise_differs = false;
    let (mut worst_db, mut worst_deg) = (0.0f64, 0.0f64);
    for (a, b) in &band {
        assert_eq!(a[0], b[0], "the same frequencies");
        let d_db = (a[1] - b[1]).abs();
        // Phases in (-180, 180]: the difference taken around the circle.
        let d_deg = ((a[2] - b[2] + 540.0).rem_euclid(360.0) - 180.0).abs();
        assert!(
            d_db < 0.2 && d_deg < 2.0,
            "at {:.4} GHz: {:.3} dB {:.3} deg, then {:.3} dB {:.3} deg",
            a[0] / 1e9,
            a[1],
            a[2],
            b[1],
            b[2]
        );
        worst_db = worst_db.max(d_db);
        worst_deg = worst_deg.max(d_deg);
        noise_differs |= d_db > 0.0;
    }
    // Two seeds, two noise realisations: the tables are not the same file twice.
    assert!(noise_differs, "the seeds gave identical tables");
    eprintln!("two calibrations differ by at most {worst_db:.4} dB and {worst_deg:.4} degrees");
}
