//! Measures what the detectors of `radbench::dsp::detect` find, for docs/detection.md:
//!
//! 1. two pillars: how close and how much weaker the second one can be and still be found, for
//!    CLEAN, the CFAR variants and the capture's former CA-CFAR + side-lobe mask;
//! 2. one pillar: detection probability against its SNR in the profile;
//! 3. noise only: false targets per profile against the false-alarm probability.
//!
//! Every profile goes through the real kernels (tests/support/detect): the thesis MSK-LFM through
//! the correlation profiler, the thesis OFDM frame through the Fourier receiver, 37 dB per sample at
//! 16 GSa/s for a unit echo, the bench's leakage (0.01 at 3 cm) present.
//!
//! Run: `cargo run --release --example detect_limits` (about a minute; `--quick` for fewer trials).

#[path = "../tests/support/detect/mod.rs"]
mod detect_support;

use detect_support::*;
use num_complex::Complex64;
use radbench::dsp::C0;
use radbench::dsp::{find_peaks, interpolate_peak, Axis, CaCfar, Interpolation};
use radbench::dsp::{CfarKind, DetectOptions, Detector, Method, NoiseEstimate};
use radbench::rng::SplitMix64;
use std::f64::consts::PI;

/// A detector under study: ranges found in the window.
enum Under {
    New(Box<Detector>),
    Legacy,
}

impl Under {
    fn ranges(&mut self, z: &[Complex64], axis: Axis) -> Vec<f64> {
        match self {
            Under::New(d) => d
                .detect(z, axis, WINDOW)
                .unwrap()
                .targets
                .iter()
                .map(|t| t.range_m)
                .collect(),
            Under::Legacy => legacy(z, axis),
        }
    }
}

/// The capture's detector before dsp::detect (src/measure/process.rs): CA-CFAR with guard 2 and
/// training 8 resolution cells per side on the power profile, peaks with 3 dB prominence, a peak
/// under -20 log10(pi d) + 3 dB of a stronger one (d in resolution cells) dropped as a side-lobe.
fn legacy(z: &[Complex64], axis: Axis) -> Vec<f64> {
    let amp: Vec<f64> = z.iter().map(|v| v.norm()).collect();
    let db: Vec<f64> = amp.iter().map(|a| 20.0 * a.max(1e-300).log10()).collect();
    let power: Vec<f64> = amp.iter().map(|a| a * a).collect();
    let cells = ((C0 / 2e9) / axis.step).max(1.0);
    let guard = (2.0 * cells).ceil() as usize;
    let training = (8.0 * cells).ceil() as usize;
    let mut cfar = CaCfar::new(guard, training, 1e-6).unwrap();
    let mut thresholds = vec![0.0; power.len()];
    cfar.detect(&power, &mut thresholds).unwrap();
    let mut candidates: Vec<(usize, f64)> = find_peaks(&db, 3.0)
        .into_iter()
        .filter(|pk| {
            WINDOW.contains(&axis.at(pk.index as f64)) && power[pk.index] > thresholds[pk.index]
        })
        .map(|pk| (pk.index, pk.value))
        .collect();
    candidates.sort_by(|a, b| b.1.total_cmp(&a.1));
    let mut kept: Vec<(usize, f64)> = Vec::new();
    for c in candidates {
        let masked = kept.iter().any(|k| {
            let d = (c.0 as f64 - k.0 as f64).abs() / cells;
            let mask = if d < 1.0 {
                0.0
            } else {
                -20.0 * (PI * d).log10()
            };
            c.1 < k.1 + mask + 3.0
        });
        if !masked {
            kept.push(c);
        }
    }
    kept.iter()
        .map(|&(i, _)| axis.at(interpolate_peak(&amp, i, Interpolation::ParabolicDb).0))
        .collect()
}

fn methods() -> Vec<(&'static str, Option<Method>)> {
    let os = CfarKind::Os { rank: 0.75 };
    vec![
        (
            "CLEAN",
            Some(Method::Clean {
                noise: NoiseEstimate::Global,
            }),
        ),
        (
            "CLEAN+OS",
            Some(Method::Clean {
                noise: NoiseEstimate::Local(os),
            }),
        ),
        ("CLEAN, floor -60 dB", None),
        ("OS-CFAR", Some(Method::Cfar { kind: os })),
        ("CA-CFAR", Some(Method::Cfar { kind: CfarKind::Ca })),
        ("GO-CFAR", Some(Method::Cfar { kind: CfarKind::Go })),
        ("SO-CFAR", Some(Method::Cfar { kind: CfarKind::So })),
        ("old CA+mask", None),
    ]
}

/// Position tolerance for "found" in the two-pillar study, m.
const TOL_M: f64 = 0.02;

fn two_pillars(quick: bool) {
    let trials = if quick { 6 } else { 20 };
    let seps = [1.0, 1.5, 2.0, 3.0];
    let weaker = [0.0, 10.0, 20.0, 30.0, 40.0];
    println!("## Two pillars\n");
    println!(
        "Success rate over {trials} scenes per cell: both pillars found within {} cm and nothing \
         else in 0.15-10 m. Strong pillar amplitude 1 at 1.5-6 m, the second one `d` resolution \
         cells (c0/2B = 15 cm) farther or nearer, weaker by the column's dB; random phases and \
         sub-cell positions; leakage 0.01 at 3 cm; 37 dB per sample at 16 GSa/s.\n",
        TOL_M * 100.0
    );
    for wave in [Wave::MskLfm, Wave::Ofdm] {
        let mut bench = Bench::new(wave);
        let axis = bench.axis;
        let mut unders: Vec<(&str, Under)> = methods()
            .into_iter()
            .map(|(name, m)| {
                (
                    name,
                    match m {
                        Some(method) => Under::New(Box::new(bench.detector(DetectOptions {
                            method,
                            ..DetectOptions::default()
                        }))),
                        None if name.starts_with("CLEAN") => {
                            Under::New(Box::new(bench.detector(DetectOptions {
                                model_floor_db: -60.0,
                                ..DetectOptions::default()
                            })))
                        }
                        None => Under::Legacy,
                    },
                )
            })
            .collect();
        println!("### {}\n", wave.name());
        print!("| detector | d (cells) |");
        for w in weaker {
            print!(" -{w} dB |");
        }
        println!();
        print!("|---|---|");
        for _ in weaker {
            print!("---|");
        }
        println!();
        let mut table = vec![vec![vec![0usize; weaker.len()]; seps.len()]; unders.len()];
        for (si, &sep) in seps.iter().enumerate() {
            for (wi, &w) in weaker.iter().enumerate() {
                let mut rng = SplitMix64::new(1000 + (si * 10 + wi) as u64);
                for trial in 0..trials {
                    let r = 1.5 + 4.5 * rng.uniform();
                    let side = if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
                    let pillars = [
                        Pillar {
                            range_m: r,
                            amp: 1.0,
                            phase: 2.0 * PI * rng.uniform(),
                        },
                        Pillar {
                            range_m: r + side * sep * RES_M,
                            amp: 10f64.powf(-w / 20.0),
                            phase: 2.0 * PI * rng.uniform(),
                        },
                    ];
                    let mut scene = pillars.to_vec();
                    scene.push(leakage(0.01));
                    let z = bench
                        .scene(
                            &scene,
                            Some(SNR_DB),
                            trial as u64 + 7919 * (si * 10 + wi) as u64,
                        )
                        .to_vec();
                    for (ui, (_, under)) in unders.iter_mut().enumerate() {
                        let found = under.ranges(&z, axis);
                        let (matched, extra) = match_targets(&pillars, &found, TOL_M);
                        if matched.iter().all(Option::is_some) && extra.is_empty() {
                            table[ui][si][wi] += 1;
                        }
                    }
                }
            }
        }
        for (ui, (name, _)) in unders.iter().enumerate() {
            for (si, &sep) in seps.iter().enumerate() {
                print!("| {name} | {sep} |");
                for hits in &table[ui][si] {
                    print!(" {:.0} % |", 100.0 * *hits as f64 / trials as f64);
                }
                println!();
            }
        }
        println!();
    }
}

fn detection_probability(quick: bool) {
    let trials = if quick { 20 } else { 100 };
    let snrs = [10.0, 13.0, 16.0, 19.0, 22.0];
    println!("## One pillar near the noise\n");
    println!(
        "Detection probability of one pillar (found within 3 cm, random range 1-8 m, phase, \
         sub-cell position) against its SNR in the profile (|a|^2 over the noise power per cell), \
         CLEAN, default Pfa 1e-6; {trials} scenes per column. The SNR per sample is set to give \
         the column's profile SNR.\n"
    );
    print!("| profile | false targets |");
    for s in snrs {
        print!(" {s} dB |");
    }
    println!();
    print!("|---|---|");
    for _ in snrs {
        print!("---|");
    }
    println!();
    for wave in [Wave::MskLfm, Wave::Ofdm] {
        let mut bench = Bench::new(wave);
        let axis = bench.axis;
        let mut det = bench.detector(DetectOptions::default());
        // Profile noise power per cell for unit per-sample noise, measured on noise alone.
        let z = bench.scene(&[], Some(0.0), 5).to_vec();
        let unit_noise = det.detect(&z, axis, WINDOW).unwrap().noise_power.unwrap();
        let mut false_targets = 0;
        let mut row = String::new();
        for (si, &snr) in snrs.iter().enumerate() {
            let mut rng = SplitMix64::new(77 + si as u64);
            let mut hits = 0;
            for trial in 0..trials {
                let p = Pillar {
                    range_m: 1.0 + 7.0 * rng.uniform(),
                    amp: 1.0,
                    phase: 2.0 * PI * rng.uniform(),
                };
                // amp^2 / (sigma^2 unit_noise) = snr  =>  sigma^2 = 1 / (snr unit_noise).
                let per_sample_db = snr + 10.0 * unit_noise.log10();
                let z = bench
                    .scene(
                        &[p],
                        Some(per_sample_db),
                        500 + trial as u64 + 1000 * si as u64,
                    )
                    .to_vec();
                let found: Vec<f64> = det
                    .detect(&z, axis, WINDOW)
                    .unwrap()
                    .targets
                    .iter()
                    .map(|t| t.range_m)
                    .collect();
                let (matched, extra) = match_targets(&[p], &found, 0.03);
                hits += usize::from(matched[0].is_some());
                false_targets += extra.len();
            }
            row += &format!(" {:.0} % |", 100.0 * hits as f64 / trials as f64);
        }
        println!("| {} | {false_targets} |{row}", wave.name());
    }
    println!();
}

fn false_alarms(quick: bool) {
    let profiles = if quick { 100 } else { 1000 };
    let pfas = [1e-2, 1e-3, 1e-4, 1e-6];
    println!("## Noise only\n");
    println!(
        "False targets per profile on noise alone (Tx off), CLEAN with the global noise estimate, \
         {profiles} profiles per column, against `Pfa n / noise_cells` (n cells in the profile, \
         `noise_cells` from the spread).\n"
    );
    println!(
        "| profile | n | noise_cells | Pfa | false targets per profile | Pfa n / noise_cells |"
    );
    println!("|---|---|---|---|---|---|");
    for wave in [Wave::MskLfm, Wave::Ofdm] {
        let mut bench = Bench::new(wave);
        let axis = bench.axis;
        for pfa in pfas {
            let mut det = bench.detector(DetectOptions {
                pfa,
                ..DetectOptions::default()
            });
            let mut count = 0;
            let mut n = 0;
            for seed in 0..profiles {
                let z = bench
                    .scene(&[], Some(SNR_DB), 90_000 + seed as u64)
                    .to_vec();
                n = z.len();
                let d = det.detect(&z, axis, -1e9..=1e9).unwrap();
                count += d.targets.len();
            }
            let nc = det.shape().noise_cells;
            println!(
                "| {} | {n} | {nc:.1} | {pfa:e} | {:.4} | {:.4} |",
                wave.name(),
                count as f64 / profiles as f64,
                pfa * n as f64 / nc
            );
        }
    }
    println!();
}

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let start = std::time::Instant::now();
    two_pillars(quick);
    detection_probability(quick);
    false_alarms(quick);
    eprintln!("done in {:.0} s", start.elapsed().as_secs_f64());
}
