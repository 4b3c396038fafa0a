//! The physics of the simulated bench: what the scope's I and Q channels show, given what the AWG
//! plays, the state of the front ends and the targets in front of the antennas.
//!
//! The chain, in the order it is applied:
//!
//! 1. The AWG loops one segment of signed 8-bit codes on I (channel 1) and Q (channel 2); a code `c`
//!    leaves the DAC as `c * Vpp / 255` volts. Its interpolation filter is modelled as ideal (the
//!    segment is band-limited and periodic, so the analogue signal is its Fourier series).
//! 2. The Tx up-converts it when enabled (its attenuation, and the Rx's, lower every path); every
//!    path — each target, each static clutter reflector and the direct Tx->Rx leakage — delays it by
//!    `tau = 2 R / c0` plus the fixed system delay (cables, marker latency) and rotates it by the
//!    physical carrier phase `exp(-j 2 pi f_c tau)` at the configured RF (80 GHz by default). A moving
//!    target adds its Doppler `exp(-j 2 pi (2 v f_c / c0) t)`; range migration within one capture
//!    (micrometres) is ignored.
//! 3. The Rx down-converts when enabled; residual phase noise (a Wiener process), I/Q imbalance and DC
//!    offset are applied; thermal noise is added at the configured SNR.
//! 4. The scope samples at an integer multiple of the AWG rate (80 GSa/s), starting at its trigger
//!    offset after the marker edge (plus trigger jitter), and quantises with its 8-bit ADC over eight
//!    vertical divisions, clipping at the screen edges. Samples are delivered as 16-bit words with the
//!    8-bit code in the upper byte, as the LeCroy scope does with `CFMT DEF9,WORD,BIN`.
//!
//! A scene's `[chain]` (module `chain`, preset `ideal` by default) makes the chain a real bench's:
//! the Tx side (DAC sinc, roll-off, Tx I/Q errors, compression) and the RF response shape the
//! segment's spectrum once per segment; a second path per target joins step 2; with shared-LO phase
//! noise the paths are rendered over the record (module `lo_noise`, on the grid of module `sampling`); a timebase offset or an Rx
//! skew moves the scope's sampling instants in step 4.
//!
//! SNR is defined as in radbench's thesis notes: per target of unit amplitude, per complex sample at
//! the capture rate, relative to the mean power of the waveform loaded in the AWG.
//!
//! Synthesis costs one FFT of the AWG segment and one inverse FFT at the capture rate per capture
//! (plus one per moving target): a 1 280 000-sample capture takes a few tens of milliseconds.

use num_complex::Complex64;
use rustfft::{Fft, FftPlanner};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::f64::consts::PI;
use std::sync::Arc;

/// One reflector in front of the antennas.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Target {
    /// One-way distance from the antennas, metres.
    pub range_m: f64,
    /// Voltage gain of this path from the AWG output to the scope input (linear).
    #[serde(default = "default_amplitude")]
    pub amplitude: f64,
    /// Radial velocity, m/s; positive moves away from the radar.
    #[serde(default)]
    pub velocity_mps: f64,
}

fn default_amplitude() -> f64 {
    0.5
}

/// The direct Tx -> Rx path between the two horns.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Leakage {
    /// Voltage gain of the leakage path (linear).
    pub amplitude: f64,
    /// Its delay, seconds (before the system delay is added).
    pub delay_s: f64,
}

impl Default for Leakage {
    fn default() -> Self {
        Self {
            amplitude: 0.01,
            delay_s: 0.2e-9,
        }
    }
}

/// Receiver impairments.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct Impairments {
    /// DC offset added to I and Q at the scope input, volts.
    #[serde(deserialize_with = "exactly_two")]
    pub dc_offset_v: [f64; 2],
    /// Q gain relative to I, dB.
    pub iq_gain_db: f64,
    /// Q phase error relative to I, degrees.
    pub iq_phase_deg: f64,
    /// Residual phase-noise linewidth after LO sharing, Hz (0 = none).
    pub phase_noise_linewidth_hz: f64,
}

/// `[I, Q]`: exactly two numbers. serde's own `[f64; 2]` takes the first two of a longer TOML
/// array and drops the rest without a word.
fn exactly_two<'de, D: serde::Deserializer<'de>>(d: D) -> Result<[f64; 2], D::Error> {
    let values = Vec::<f64>::deserialize(d)?;
    <[f64; 2]>::try_from(values.as_slice()).map_err(|_| {
        serde::de::Error::custom(format!(
            "dc_offset_v takes exactly 2 values, [I, Q] in volts; got {}",
            values.len()
        ))
    })
}

/// Everything about the bench that is not an instrument setting. Loaded from a TOML scene file and
/// changed at run time through the control channel.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Scene {
    /// RF carrier, Hz (sets the echo phase and Doppler).
    pub carrier_hz: f64,
    /// The targets, measured by the radar.
    pub targets: Vec<Target>,
    /// Static clutter (walls, table, mounts): reflectors that do not move between captures.
    pub clutter: Vec<Target>,
    /// Direct Tx -> Rx leakage.
    pub leakage: Leakage,
    /// SNR per unit-amplitude target per complex sample at the capture rate, dB.
    pub snr_db: f64,
    /// Fixed delay of cables, horns and marker latency, seconds: calibrated out by radbench.
    pub system_delay_s: f64,
    /// RMS trigger jitter, seconds.
    pub trigger_jitter_s: f64,
    /// Receiver impairments.
    pub impairments: Impairments,
    /// The AWG -> Tx -> Rx -> scope chain (`[chain]`, preset `ideal` by default).
    pub chain: Chain,
    /// Seed of the noise and jitter generator (each capture advances it).
    pub seed: u64,
    /// A fixed reference reflector (`[reference]`: a corner reflector on the table that never
    /// moves), named so that radbench's phase ranging can take it as the time and phase
    /// reference of every record; none by default.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference: Option<Target>,
    /// The lab's simulated clock at this scene's first capture, seconds: the chain's drift
    /// (`[chain] drift_ps_per_min`, `drift_deg_per_min`) is taken at it. In a capture's ground
    /// truth: the clock at that capture.
    pub clock_s: f64,
    /// Simulated time between two captures, seconds (the clock advances by it per capture).
    pub capture_interval_s: f64,
}

impl Default for Scene {
    fn default() -> Self {
        Self {
            carrier_hz: 80e9,
            targets: vec![Target {
                range_m: 1.0,
                amplitude: 0.5,
                velocity_mps: 0.0,
            }],
            clutter: Vec::new(),
            leakage: Leakage::default(),
            snr_db: 30.0,
            system_delay_s: 2.5e-9,
            trigger_jitter_s: 0.0,
            impairments: Impairments::default(),
            chain: Chain::default(),
            seed: 1,
            reference: None,
            clock_s: 0.0,
            capture_interval_s: DEFAULT_CAPTURE_INTERVAL_S,
        }
    }
}

/// Simulated time between two captures by default, seconds: a lab engineer's capture, look and
/// next capture.
const DEFAULT_CAPTURE_INTERVAL_S: f64 = 1.0;

impl Scene {
    /// Parses and validates a scene from TOML text; `origin` names the file in error messages.
    pub fn from_toml(text: &str, origin: &str) -> Result<Self, SceneError> {
        let scene: Scene = toml::from_str(text).map_err(|e| SceneError::Parse {
            path: origin.to_string(),
            message: e.to_string(),
        })?;
        scene.validate().map_err(|err| match err {
            SceneError::Invalid { field, message } => match locate::line_of_field(text, &field) {
                Some(line) => SceneError::Field {
                    path: origin.to_string(),
                    line,
                    field,
                    message,
                },
                None => SceneError::Parse {
                    path: origin.to_string(),
                    message: format!("`{field}`: {message}"),
                },
            },
            other => other,
        })?;
        Ok(scene)
    }

    /// Checks every field against what the physics can represent.
    pub fn validate(&self) -> Result<(), SceneError> {
        finite_in("carrier_hz", self.carrier_hz, 0.0, 1e12)?;
        finite_in("snr_db", self.snr_db, -60.0, 200.0)?;
        finite_in("system_delay_s", self.system_delay_s, 0.0, 1e-6)?;
        finite_in("trigger_jitter_s", self.trigger_jitter_s, 0.0, 1e-9)?;
        finite_in("leakage.amplitude", self.leakage.amplitude, 0.0, 10.0)?;
        finite_in("leakage.delay_s", self.leakage.delay_s, 0.0, 1e-6)?;
        finite_in("clock_s", self.clock_s, 0.0, 1e9)?;
        finite_in("capture_interval_s", self.capture_interval_s, 0.0, 1e6)?;
        if let Some(r) = &self.reference {
            finite_in("reference.range_m", r.range_m, 0.0, 150.0)?;
            finite_in("reference.amplitude", r.amplitude, 0.0, 10.0)?;
            if r.velocity_mps != 0.0 {
                return Err(invalid(
                    "reference.velocity_mps",
                    "the reference reflector is fixed: 0 (or leave it out)",
                ));
            }
        }
        for (list, name) in [(&self.targets, "targets"), (&self.clutter, "clutter")] {
            if list.len() > MAX_REFLECTORS {
                return Err(invalid(
                    name,
                    format!(
                        "{} entries; at most {MAX_REFLECTORS} (each costs synthesis time on every capture)",
                        list.len()
                    ),
                ));
            }
            for (i, t) in list.iter().enumerate() {
                finite_in(&format!("{name}[{i}].range_m"), t.range_m, 0.0, 150.0)?;
                finite_in(&format!("{name}[{i}].amplitude"), t.amplitude, 0.0, 10.0)?;
                finite_in(
                    &format!("{name}[{i}].velocity_mps"),
                    t.velocity_mps,
                    -1000.0,
                    1000.0,
                )?;
            }
        }
        let imp = &self.impairments;
        for (k, v) in imp.dc_offset_v.iter().enumerate() {
            finite_in(&format!("impairments.dc_offset_v[{k}]"), *v, -1.0, 1.0)?;
        }
        finite_in("impairments.iq_gain_db", imp.iq_gain_db, -6.0, 6.0)?;
        finite_in("impairments.iq_phase_deg", imp.iq_phase_deg, -45.0, 45.0)?;
        finite_in(
            "impairments.phase_noise_linewidth_hz",
            imp.phase_noise_linewidth_hz,
            0.0,
            1e9,
        )?;
        self.chain.validate()
    }
}

/// Most targets, and most clutter reflectors, a scene may hold.
pub(crate) const MAX_REFLECTORS: usize = 100;

/// What the AWG is playing, as the scene needs it.
#[derive(Debug, Clone, Copy)]
pub struct AwgPlayback<'a> {
    /// Channel 1 codes (I), one period of the looped segment.
    pub i: &'a [i8],
    /// Channel 2 codes (Q), same length.
    pub q: &'a [i8],
    /// Sample rate of the segment (after the AWG's divider), Sa/s.
    pub sample_rate: f64,
    /// Peak-to-peak amplitude of channels 1 and 2, volts.
    pub amplitude_vpp: [f64; 2],
    /// Index within the segment where the marker's rising edge sits.
    pub marker_index: usize,
    /// Whether channels 1 and 2 are on and the AWG is running.
    pub playing: bool,
    /// Whether the marker output (channel 3) is on.
    pub marker_out: bool,
}

/// The front ends' state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrontEnds {
    pub tx_enabled: bool,
    pub tx_attenuation_db: f64,
    pub rx_enabled: bool,
    pub rx_attenuation_db: f64,
}

impl FrontEnds {
    /// Both enabled at full gain: what a test wants when it does not model the front ends.
    pub const ALL_ON: FrontEnds = FrontEnds {
        tx_enabled: true,
        tx_attenuation_db: 0.0,
        rx_enabled: true,
        rx_attenuation_db: 0.0,
    };

    fn path_gain(&self) -> f64 {
        if !(self.tx_enabled && self.rx_enabled) {
            return 0.0;
        }
        10f64.powf(-(self.tx_attenuation_db + self.rx_attenuation_db) / 20.0)
    }
}

/// How the scope acquires.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CaptureSetup {
    /// Sample rate, Sa/s: an integer multiple of the AWG rate.
    pub sample_rate: f64,
    /// Number of points to acquire per channel.
    pub points: usize,
    /// Time of the first point relative to the trigger, seconds (LeCroy's HORIZ_OFFSET; negative =
    /// pre-trigger samples).
    pub trigger_offset_s: f64,
    /// Vertical scale of channels 1 and 2, volts per division (eight divisions full screen).
    pub volts_per_div: [f64; 2],
    /// Vertical offset of channels 1 and 2, volts (added before quantisation, as LeCroy's OFFSET).
    pub offset_v: [f64; 2],
}

/// One acquisition of both channels.
#[derive(Debug, Clone)]
pub struct Capture {
    /// Channel 1 (I) as 16-bit words, the 8-bit ADC code in the upper byte.
    pub i_words: Vec<i16>,
    /// Channel 2 (Q), same format.
    pub q_words: Vec<i16>,
    /// Volts per word LSB for channels 1 and 2: volts = gain * word - offset.
    pub vertical_gain: [f64; 2],
    /// Vertical offset (volts) for channels 1 and 2, as in WAVEDESC.
    pub vertical_offset: [f64; 2],
    /// Sample period, seconds.
    pub horiz_interval: f64,
    /// First sample relative to the trigger, seconds (with this capture's jitter).
    pub horiz_offset: f64,
    /// Samples that hit the ADC's top or bottom code, per channel.
    pub clipped: [usize; 2],
    /// The scene as it was for this capture: the ground truth.
    pub scene: Scene,
}

/// Scope ADC resolution.
const ADC_BITS: u32 = 8;
/// Vertical divisions on the scope's screen, spanned by the ADC's full range.
const DIVISIONS: f64 = 8.0;

/// Synthesises captures; holds FFT plans and the last segment's spectrum between captures.
pub struct Synthesizer {
    planner: FftPlanner<f64>,
    plans: HashMap<(usize, bool), Arc<dyn Fft<f64>>>,
    /// Spectrum of the last segment, keyed by a hash of its codes, rate and amplitudes.
    cached: Option<(u64, Arc<[Complex64]>, f64)>,
    rng: SplitMix64,
    /// Buffers kept from one acquisition to the next: a record is megabytes, and fresh ones
    /// cost page faults and zeroing that took more time than the synthesis itself.
    record: Vec<Complex64>,
    period: Vec<Complex64>,
    transfer: Vec<Complex64>,
    scratch: Vec<Complex64>,
    /// The grid a warped capture (timebase offset, Rx skew) is rendered on.
    warped: Vec<Complex64>,
    /// The LO's phasor and the transmitted signal on the grid (shared-LO phase noise).
    lo_phase: Vec<Complex64>,
    lo_tx: Vec<Complex64>,
    lo_rx: Vec<Complex64>,
    /// The last record before its noise, and what it was rendered from ([`clean_key`]).
    clean: Option<(u64, Vec<Complex64>)>,
    /// Captures synthesised so far: the simulated clock advances by the scene's
    /// `capture_interval_s` per capture.
    captures: u64,
    /// The simulated clock of the last capture, seconds.
    last_clock_s: f64,
}

impl Synthesizer {
    pub fn new(seed: u64) -> Self {
        Self {
            planner: FftPlanner::new(),
            plans: HashMap::new(),
            cached: None,
            rng: SplitMix64::new(seed),
            record: Vec::new(),
            period: Vec::new(),
            transfer: Vec::new(),
            scratch: Vec::new(),
            warped: Vec::new(),
            lo_phase: Vec::new(),
            lo_tx: Vec::new(),
            lo_rx: Vec::new(),
            clean: None,
            captures: 0,
            last_clock_s: 0.0,
        }
    }

    /// The simulated clock of the last capture, seconds (the scene's `clock_s` plus
    /// `capture_interval_s` per capture before it): what its ground truth records.
    pub(crate) fn last_clock_s(&self) -> f64 {
        self.last_clock_s
    }

    /// Forgets the last record before its noise, so the next is rendered afresh.
    #[cfg(test)]
    pub(crate) fn forget_clean(&mut self) {
        self.clean = None;
    }

    /// Restarts the noise and jitter generator from `seed`.
    pub fn reseed(&mut self, seed: u64) {
        self.rng = SplitMix64::new(seed);
    }

    fn plan(&mut self, len: usize, inverse: bool) -> Arc<dyn Fft<f64>> {
        let planner = &mut self.planner;
        self.plans
            .entry((len, inverse))
            .or_insert_with(|| {
                if inverse {
                    planner.plan_fft_inverse(len)
                } else {
                    planner.plan_fft_forward(len)
                }
            })
            .clone()
    }

    /// The spectrum of the segment in volts (unnormalised FFT) as it leaves the Tx, shaped by the
    /// chain's Tx side and its response, and the mean power of the segment as loaded; cached.
    fn segment_spectrum(
        &mut self,
        awg: &AwgPlayback<'_>,
        chain: &ChainParams,
    ) -> (Arc<[Complex64]>, f64) {
        let key = segment_key(awg, chain);
        if let Some((k, spec, power)) = &self.cached {
            if *k == key {
                return (spec.clone(), *power);
            }
        }
        let (si, sq) = (awg.amplitude_vpp[0] / 255.0, awg.amplitude_vpp[1] / 255.0);
        let mut x: Vec<Complex64> = awg
            .i
            .iter()
            .zip(awg.q)
            .map(|(&i, &q)| Complex64::new(f64::from(i) * si, f64::from(q) * sq))
            .collect();
        let power = x.iter().map(|v| v.norm_sqr()).sum::<f64>() / x.len().max(1) as f64;
        let fft = self.plan(x.len(), false);
        fft.process(&mut x);
        if !chain.is_ideal() {
            self.shape_tx(&mut x, awg.sample_rate, chain);
        }
        let x: Arc<[Complex64]> = x.into();
        self.cached = Some((key, x.clone(), power));
        (x, power)
    }

    /// The chain's Tx side and response on the segment's spectrum `x` (rate `fs`): the DAC and
    /// analogue filters and the I/Q errors on I and Q apart, the Tx's compression in time, then
    /// the RF response.
    fn shape_tx(&mut self, x: &mut [Complex64], fs: f64, chain: &ChainParams) {
        let l = x.len();
        let freq = |k: usize| signed_bin(k, l) as f64 * fs / l as f64;
        if chain.dac_sinc || chain.bandwidth_hz > 0.0 || chain.tx_widely_linear() {
            let g = 10f64.powf(chain.tx_iq_gain_db / 20.0);
            let (s, c) = chain.tx_iq_phase_deg.to_radians().sin_cos();
            let skew = chain.tx_iq_skew_ps * 1e-12;
            let orig = x.to_vec();
            for (k, v) in x.iter_mut().enumerate() {
                // I and Q are real: their spectra are the conjugate-symmetric parts of x.
                let mirror = orig[(l - k) % l].conj();
                let i = (orig[k] + mirror) * 0.5;
                let q = (orig[k] - mirror) * Complex64::new(0.0, -0.5);
                let f = freq(k);
                let q = (q * c - i * s) * g * Complex64::from_polar(1.0, -2.0 * PI * f * skew);
                *v = (i + Complex64::i() * q) * chain.channel_filter(f, fs);
            }
        }
        if chain.tx_p1db_v.is_finite() {
            self.plan(l, true).process(x);
            for v in x.iter_mut() {
                *v = chain.compress(*v / l as f64);
            }
            self.plan(l, false).process(x);
        }
        for (k, v) in x.iter_mut().enumerate() {
            *v *= chain.response_at(freq(k));
        }
    }

    /// One acquisition of the scene as the scope would make it (volts through its 8-bit ADC).
    pub fn capture(
        &mut self,
        scene: &Scene,
        awg: &AwgPlayback<'_>,
        front: FrontEnds,
        setup: &CaptureSetup,
    ) -> Result<Capture, SceneError> {
        check_vertical(setup)?;
        let (_, horiz_offset) = self.volts(
            scene,
            awg,
            front,
            setup.sample_rate,
            setup.points,
            setup.trigger_offset_s,
        )?;
        let truth = Scene {
            clock_s: self.last_clock_s,
            ..scene.clone()
        };
        Ok(quantise(&self.record, setup, horiz_offset, truth))
    }

    /// What the scope's inputs see (I + jQ in volts, before its ADC) for `points` samples at
    /// `sample_rate` from `first_point_s` after the marker edge; also returns that offset with this
    /// acquisition's trigger jitter added.
    pub fn volts(
        &mut self,
        scene: &Scene,
        awg: &AwgPlayback<'_>,
        front: FrontEnds,
        sample_rate: f64,
        points: usize,
        first_point_s: f64,
    ) -> Result<(&[Complex64], f64), SceneError> {
        check_rates(awg, sample_rate, points)?;
        let chain = scene.chain.resolve();
        let l = awg.i.len();
        let up = (sample_rate / awg.sample_rate).round() as usize;
        let period = l * up;
        let clock_s = scene.clock_s + self.captures as f64 * scene.capture_interval_s;
        self.captures += 1;
        self.last_clock_s = clock_s;
        let jitter = scene.trigger_jitter_s * self.rng.gaussian();
        let horiz_offset = first_point_s + jitter;
        // A timebase offset or an Rx skew samples between the grid's points: render a grid that
        // covers those instants, then interpolate.
        let warp = Warp::new(&chain, horiz_offset, sample_rate, points);
        let (first, len) = warp
            .as_ref()
            .map_or((horiz_offset, points), |w| (w.start / sample_rate, w.len));
        // The marker edge (the trigger) leaves with segment sample `marker_index`; the grid starts
        // `first` after it.
        let t0 = awg.marker_index as f64 / awg.sample_rate + first;

        let (spectrum, power) = self.segment_spectrum(awg, &chain);
        let mut y = std::mem::take(&mut self.record);
        y.clear();
        let gain = if awg.playing { front.path_gain() } else { 0.0 };
        let paths = if gain > 0.0 {
            paths(scene, &chain, clock_s)
        } else {
            Vec::new()
        };
        let linewidth = scene.impairments.phase_noise_linewidth_hz;
        let lo_noise = gain > 0.0 && chain.shared_lo && linewidth > 0.0;
        // The record before its noise is the same for every capture of a still scene without
        // trigger jitter or shared-LO phase noise: rendered once (a 16-segment sequence spent
        // half its synthesis rendering the same period again).
        let clean_key = (!lo_noise).then(|| {
            let spectrum_key = self.cached.as_ref().map_or(0, |c| c.0);
            let grid = [t0, first, horiz_offset, sample_rate];
            clean_key(spectrum_key, &paths, gain, grid, [len, points])
        });
        if let (Some(key), Some((kept, clean))) = (clean_key, &self.clean) {
            if key == *kept {
                y.extend_from_slice(clean);
                return Ok(self.noisy(y, scene, &chain, sample_rate, power, horiz_offset));
            }
        }
        y.resize(len, Complex64::new(0.0, 0.0));
        if gain > 0.0 {
            if lo_noise {
                let tx = ToGrid {
                    spectrum: &spectrum,
                    fs_awg: awg.sample_rate,
                    up,
                    t0,
                    gain,
                };
                self.render_lo_noise(&mut y, &tx, sample_rate, &paths, linewidth);
            } else {
                let (still, moving): (Vec<_>, Vec<_>) =
                    paths.iter().partition(|p| p.doppler_hz == 0.0);
                if !still.is_empty() {
                    self.render(&spectrum, awg.sample_rate, up, t0, &still, gain);
                    add_window(&mut y, &self.period, 0.0, sample_rate, t0, period);
                }
                for path in moving {
                    self.render(&spectrum, awg.sample_rate, up, t0, &[path], gain);
                    add_window(
                        &mut y,
                        &self.period,
                        path.doppler_hz,
                        sample_rate,
                        t0,
                        period,
                    );
                }
            }
        }
        if let Some(w) = &warp {
            let mut out = std::mem::take(&mut self.warped);
            w.apply(&y, &mut out);
            self.warped = y;
            y = out;
        }
        if let Some(key) = clean_key {
            let mut clean = self.clean.take().map(|(_, c)| c).unwrap_or_default();
            clean.clear();
            clean.extend_from_slice(&y);
            self.clean = Some((key, clean));
        }
        Ok(self.noisy(y, scene, &chain, sample_rate, power, horiz_offset))
    }

    /// The record `y` with the receiver's noise and impairments, kept as `self.record`.
    fn noisy(
        &mut self,
        mut y: Vec<Complex64>,
        scene: &Scene,
        chain: &ChainParams,
        sample_rate: f64,
        power: f64,
        horiz_offset: f64,
    ) -> (&[Complex64], f64) {
        // The receiver's noise enters ahead of its I/Q demodulator (the front end's noise figure
        // sets it), so the demodulator's imbalance and DC act on it too.
        let reference_power = if power > 0.0 { power } else { 0.25 * 0.25 };
        let noise_var = reference_power / 10f64.powf(scene.snr_db / 10.0);
        let sigma = (noise_var / 2.0).sqrt();
        for v in y.iter_mut() {
            *v += Complex64::new(sigma * self.rng.gaussian(), sigma * self.rng.gaussian());
        }
        self.impair(&mut y, scene, chain, sample_rate);
        self.record = y;
        (&self.record, horiz_offset)
    }

    /// One period of the sum of `paths` at `up` times the segment rate, starting at `t0` after the
    /// segment's first sample, into `self.period`.
    fn render(
        &mut self,
        spectrum: &[Complex64],
        fs: f64,
        up: usize,
        t0: f64,
        paths: &[&Path],
        gain: f64,
    ) {
        let l = spectrum.len();
        let n = l * up;
        let mut out = std::mem::take(&mut self.period);
        out.clear();
        out.resize(n, Complex64::new(0.0, 0.0));
        // Bins are placed by signed frequency so the band-limited waveform is interpolated exactly;
        // the inverse FFT of length n (unnormalised) needs 1/l to return volts.
        let scale = gain / l as f64;
        let df = fs / l as f64;
        let mut h = std::mem::take(&mut self.transfer);
        h.clear();
        h.resize(l, Complex64::new(0.0, 0.0));
        add_transfer(&mut h, df, paths, t0);
        for (k, (x, hk)) in spectrum.iter().zip(&h).enumerate() {
            let idx = signed_bin(k, l).rem_euclid(n as i64) as usize;
            out[idx] = x * hk * scale;
        }
        let ifft = self.plan(n, true);
        let need = ifft.get_inplace_scratch_len();
        if self.scratch.len() < need {
            self.scratch.resize(need, Complex64::new(0.0, 0.0));
        }
        ifft.process_with_scratch(&mut out, &mut self.scratch[..need]);
        self.period = out;
        self.transfer = h;
    }

    /// The Rx side after the scope's sampling: independent LOs' phase drift, I/Q imbalance, DC.
    fn impair(&mut self, y: &mut [Complex64], scene: &Scene, chain: &ChainParams, fs: f64) {
        let imp = &scene.impairments;
        if imp.phase_noise_linewidth_hz > 0.0 && !chain.shared_lo {
            let step = (2.0 * PI * imp.phase_noise_linewidth_hz / fs).sqrt();
            let mut phi = 0.0;
            for v in y.iter_mut() {
                phi += step * self.rng.gaussian();
                *v *= Complex64::from_polar(1.0, phi);
            }
        }
        if imp.iq_gain_db != 0.0 || imp.iq_phase_deg != 0.0 {
            let g = 10f64.powf(imp.iq_gain_db / 20.0);
            let (s, c) = imp.iq_phase_deg.to_radians().sin_cos();
            for v in y.iter_mut() {
                let q = g * (v.im * c - v.re * s);
                v.im = q;
            }
        }
        let [di, dq] = imp.dc_offset_v;
        if di != 0.0 || dq != 0.0 {
            for v in y.iter_mut() {
                v.re += di;
                v.im += dq;
            }
        }
    }
}

/// One propagation path, resolved to delay, amplitude and Doppler.
#[derive(Debug, Clone, Copy)]
struct Path {
    delay_s: f64,
    amplitude: f64,
    carrier_hz: f64,
    doppler_hz: f64,
    /// Extra phase (a bounce's reflection), radians.
    phase_rad: f64,
}

/// Every path at `clock_s` on the simulated clock (the chain's drift taken there).
fn paths(scene: &Scene, chain: &ChainParams, clock_s: f64) -> Vec<Path> {
    let mut out = Vec::with_capacity(2 * scene.targets.len() + scene.clutter.len() + 2);
    let bounce = chain.multipath_ratio();
    let (drift_s, drift_rad) = chain.drift_at(clock_s);
    let system_delay_s = scene.system_delay_s + drift_s;
    // The reference reflector is fixed clutter with a name: after the targets, so a target's
    // second path keeps its index.
    let fixed = scene.clutter.iter().chain(&scene.reference);
    for (k, t) in scene.targets.iter().chain(fixed).enumerate() {
        let direct = Path {
            delay_s: 2.0 * t.range_m / C0 + system_delay_s,
            amplitude: t.amplitude,
            carrier_hz: scene.carrier_hz,
            doppler_hz: -2.0 * t.velocity_mps * scene.carrier_hz / C0,
            phase_rad: drift_rad,
        };
        out.push(direct);
        if bounce > 0.0 && k < scene.targets.len() {
            out.push(Path {
                delay_s: direct.delay_s + chain.multipath_delay_s(),
                amplitude: t.amplitude * bounce,
                phase_rad: drift_rad + chain.multipath_phase_deg.to_radians(),
                ..direct
            });
        }
    }
    if scene.leakage.amplitude > 0.0 {
        out.push(Path {
            delay_s: scene.leakage.delay_s + system_delay_s,
            amplitude: scene.leakage.amplitude,
            carrier_hz: scene.carrier_hz,
            doppler_hz: 0.0,
            phase_rad: drift_rad,
        });
    }
    out
}

/// The signed frequency index of FFT bin `k` of `l`.
fn signed_bin(k: usize, l: usize) -> i64 {
    if k < l / 2 || (k == l / 2 && l % 2 == 1) {
        k as i64
    } else {
        k as i64 - l as i64
    }
}

/// Adds the paths' transfer function at bins `signed_bin(k) * df` to `h`, each path delayed by
/// its delay less `t_ref`. Along a run of consecutive frequencies a path's phase grows linearly,
/// so it is advanced by a rotating phasor (re-anchored exactly every RESYNC bins to keep rounding
/// from accumulating) instead of one sincos per bin.
fn add_transfer(h: &mut [Complex64], df: f64, paths: &[&Path], t_ref: f64) {
    const RESYNC: usize = 1024;
    let l = h.len();
    for p in paths {
        let phase_at = |signed: i64| {
            p.phase_rad
                - 2.0 * PI * (p.carrier_hz * p.delay_s + signed as f64 * df * (p.delay_s - t_ref))
        };
        let step = Complex64::from_polar(1.0, -2.0 * PI * df * (p.delay_s - t_ref));
        let mut rot = Complex64::new(0.0, 0.0);
        for (k, hk) in h.iter_mut().enumerate() {
            let signed = signed_bin(k, l);
            if k % RESYNC == 0 || (k > 0 && signed != signed_bin(k - 1, l) + 1) {
                rot = Complex64::from_polar(p.amplitude, phase_at(signed));
            }
            *hk += rot;
            rot *= step;
        }
    }
}

/// Adds the record window of one rendered period to `y` (the segment loops, so the window wraps),
/// rotated by the path's Doppler.
fn add_window(
    y: &mut [Complex64],
    period: &[Complex64],
    doppler_hz: f64,
    fs: f64,
    t0: f64,
    n: usize,
) {
    // The record is the period repeated from its start; walk it in contiguous runs.
    let mut rot = Complex64::from_polar(1.0, 2.0 * PI * doppler_hz * t0);
    let step = Complex64::from_polar(1.0, 2.0 * PI * doppler_hz / fs);
    for run in y.chunks_mut(n) {
        if doppler_hz == 0.0 {
            for (v, p) in run.iter_mut().zip(period) {
                *v += p;
            }
        } else {
            for (v, p) in run.iter_mut().zip(period) {
                *v += p * rot;
                rot *= step;
            }
        }
    }
}

fn check_rates(awg: &AwgPlayback<'_>, sample_rate: f64, points: usize) -> Result<(), SceneError> {
    if awg.i.len() != awg.q.len() {
        return Err(SceneError::Synthesis(format!(
            "I has {} samples but Q has {}: load both channels with segments of the same length",
            awg.i.len(),
            awg.q.len()
        )));
    }
    if awg.i.is_empty() {
        return Err(SceneError::Synthesis("the AWG holds no waveform".into()));
    }
    if !(awg.sample_rate > 0.0 && sample_rate > 0.0) {
        return Err(SceneError::Synthesis(
            "sample rates must be positive".into(),
        ));
    }
    let ratio = sample_rate / awg.sample_rate;
    if ratio < 1.0 || (ratio - ratio.round()).abs() > 1e-9 * ratio {
        return Err(SceneError::Synthesis(format!(
            "the scope rate {sample_rate} Sa/s must be an integer multiple of the AWG rate {} Sa/s",
            awg.sample_rate
        )));
    }
    if points == 0 || points > MAX_POINTS {
        return Err(SceneError::Synthesis(format!(
            "{points} points per channel: the emulated scope records 1 ..= {MAX_POINTS} points"
        )));
    }
    Ok(())
}

fn check_vertical(setup: &CaptureSetup) -> Result<(), SceneError> {
    if setup
        .volts_per_div
        .iter()
        .any(|v| !(v.is_finite() && *v > 0.0))
    {
        return Err(SceneError::Synthesis(
            "volts per division must be positive".into(),
        ));
    }
    Ok(())
}

/// Longest record synthesised per channel.
const MAX_POINTS: usize = 64 << 20;

/// The scope's ADC: eight divisions span 2^8 codes; the 8-bit code goes in the upper byte of a word.
fn quantise(y: &[Complex64], setup: &CaptureSetup, horiz_offset: f64, scene: Scene) -> Capture {
    let levels = (1u32 << ADC_BITS) as f64;
    let mut words = [Vec::with_capacity(y.len()), Vec::with_capacity(y.len())];
    let mut clipped = [0usize; 2];
    let mut gains = [0.0; 2];
    for ch in 0..2 {
        let step = DIVISIONS * setup.volts_per_div[ch] / levels;
        gains[ch] = step / 256.0;
        let (lo, hi) = (-(levels / 2.0), levels / 2.0 - 1.0);
        for v in y {
            let volts = if ch == 0 { v.re } else { v.im } + setup.offset_v[ch];
            let code = (volts / step).round();
            let code = if code < lo || code > hi {
                clipped[ch] += 1;
                code.clamp(lo, hi)
            } else {
                code
            };
            words[ch].push((code as i16) << 8);
        }
    }
    let [i_words, q_words] = words;
    Capture {
        i_words,
        q_words,
        vertical_gain: gains,
        vertical_offset: setup.offset_v,
        horiz_interval: 1.0 / setup.sample_rate,
        horiz_offset,
        clipped,
        scene,
    }
}

/// What a record before its noise is rendered from, beyond the segment's spectrum (its
/// [`segment_key`]): the paths, the front ends' gain and the grid (its times and rate, its
/// lengths rendered and recorded).
fn clean_key(
    spectrum_key: u64,
    paths: &[Path],
    gain: f64,
    grid: [f64; 4],
    lengths: [usize; 2],
) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    spectrum_key.hash(&mut h);
    for p in paths {
        for v in [
            p.delay_s,
            p.amplitude,
            p.carrier_hz,
            p.doppler_hz,
            p.phase_rad,
        ] {
            v.to_bits().hash(&mut h);
        }
    }
    gain.to_bits().hash(&mut h);
    for v in grid {
        v.to_bits().hash(&mut h);
    }
    lengths.hash(&mut h);
    h.finish()
}

fn segment_key(awg: &AwgPlayback<'_>, chain: &ChainParams) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    awg.i.hash(&mut h);
    awg.q.hash(&mut h);
    awg.sample_rate.to_bits().hash(&mut h);
    awg.amplitude_vpp[0].to_bits().hash(&mut h);
    awg.amplitude_vpp[1].to_bits().hash(&mut h);
    format!("{chain:?}").hash(&mut h);
    h.finish()
}

/// SplitMix64 with ziggurat Gaussians: mock_lab's own seeded generator (it shares no code with
/// radbench).
#[derive(Debug, Clone)]
struct SplitMix64 {
    state: u64,
    /// The unused upper half of the last 64-bit word.
    spare_word: Option<u32>,
}

impl SplitMix64 {
    fn new(seed: u64) -> Self {
        Self {
            state: seed,
            spare_word: None,
        }
    }

    fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn next_u32(&mut self) -> u32 {
        if let Some(w) = self.spare_word.take() {
            return w;
        }
        let w = self.next_u64();
        self.spare_word = Some((w >> 32) as u32);
        w as u32
    }

    /// Uniform in (0, 1] with 53 random bits.
    fn uniform(&mut self) -> f64 {
        1.0 - (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Standard normal deviate (ziggurat).
    fn gaussian(&mut self) -> f64 {
        let this = std::cell::RefCell::new(self);
        ziggurat::normal(
            || this.borrow_mut().next_u32(),
            || this.borrow_mut().uniform(),
        )
    }
}

mod chain;
mod checks;
mod lo_noise;
mod locate;
mod sampling;
mod ziggurat;

pub use chain::{Chain, ChainParams, ChainPreset};
use checks::{finite_in, invalid};
pub use checks::{SceneError, C0};
use sampling::{ToGrid, Warp};

#[cfg(test)]
mod chain_tests;
#[cfg(test)]
mod tests;
