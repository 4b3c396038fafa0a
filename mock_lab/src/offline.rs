//! The simulated bench without its servers: the scene rendered by the same [`Synthesizer`] and
//! recorded by the same emulated LabMaster ADC as the lab's scope does it, for a caller that
//! knows what the instruments would be set to (`radbench simulate run --scene`).
//!
//! One [`OfflineScope::acquire`] is one acquisition of the lab's scope after a fresh start (or a
//! scene `set`): the generator starts from the scene's seed, and each further acquisition
//! continues it, as consecutive captures on the lab do. The steps are the lab's own:
//! [`Synthesizer::volts`] (noise, jitter, chain, impairments), the volts handed to the scope in
//! single precision as the bench's wiring hands them, the scope's record length and first point
//! from its state ([`ScopeState::request`]) and its 8-bit ADC (`ScopeState::complete`). The
//! scaling is returned as the scope's `WF? ALL` descriptor carries it (single precision).

use crate::catalog::{CatalogError, DigitizerModel};
use crate::emulator::lecroy::trigger::Capture;
use crate::emulator::lecroy::{RemoteInterface, ScopeState};
use crate::scene::{AwgPlayback, FrontEnds, Scene, SceneError, Synthesizer};

/// The scope's settings as a driver leaves them (the values it sent, as the scope parsed them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScopeSettings {
    /// Horizontal scale, seconds per division (`app.Acquisition.Horizontal.HorScale`).
    pub hor_scale_s: f64,
    /// Trigger delay, seconds (`TRDL`).
    pub trigger_delay_s: f64,
    /// Vertical scale of C1 (I) and C2 (Q), volts per division.
    pub volts_per_div: [f64; 2],
    /// Vertical offset of C1 and C2, volts.
    pub offset_v: [f64; 2],
}

/// One acquisition of C1 (I) and C2 (Q) as `WF? ALL` delivers it.
#[derive(Debug, Clone, PartialEq)]
pub struct OfflineRecord {
    /// 16-bit words, the ADC code in the upper bits.
    pub i: Vec<i16>,
    pub q: Vec<i16>,
    /// Volts per word of C1 and C2 (WAVEDESC VERTICAL_GAIN, single precision).
    pub vertical_gain: [f64; 2],
    /// Vertical offset of C1 and C2, volts (WAVEDESC VERTICAL_OFFSET, single precision).
    pub vertical_offset: [f64; 2],
    /// Sample rate, Sa/s (the scope's fixed rate).
    pub sample_rate: f64,
    /// Time of the first point after the trigger, seconds (WAVEDESC HORIZ_OFFSET).
    pub first_point_s: f64,
}

/// The lab's scope and synthesis, in-process.
pub struct OfflineScope {
    model: DigitizerModel,
    synth: Synthesizer,
}

impl OfflineScope {
    /// The built-in LabMaster model, its noise generator started from `seed` (the scene's).
    pub fn new(seed: u64) -> Result<OfflineScope, CatalogError> {
        Ok(OfflineScope {
            model: crate::catalog::lecroy()?,
            synth: Synthesizer::new(seed),
        })
    }

    /// The scope's fixed sample rate, Sa/s.
    pub fn sample_rate(&self) -> f64 {
        ScopeState::sample_rate(&self.model)
    }

    /// One acquisition of `scene` while the AWG plays `awg`, the front ends are `front` and the
    /// scope is set to `settings` (real-time mode, one segment).
    pub fn acquire(
        &mut self,
        scene: &Scene,
        awg: &AwgPlayback<'_>,
        front: FrontEnds,
        settings: &ScopeSettings,
    ) -> Result<OfflineRecord, SceneError> {
        let mut state = ScopeState::reset(&self.model, RemoteInterface::Vicp);
        state.set_hor_scale(&self.model, settings.hor_scale_s);
        state.trigger_delay_s = settings.trigger_delay_s;
        for (ch, c) in state.channels.iter_mut().take(2).enumerate() {
            c.volts_per_div = settings.volts_per_div[ch];
            c.offset_v = settings.offset_v[ch];
            c.on = true;
        }
        for c in state.channels.iter_mut().skip(2) {
            c.on = false;
        }
        let request = state.request(&self.model);
        let (y, _) = self.synth.volts(
            scene,
            awg,
            front,
            request.sample_rate,
            request.points,
            request.first_point_s,
        )?;
        // The bench hands the scope its inputs in single precision (bench::BenchSource).
        let capture = Capture {
            channels: vec![
                Some(y.iter().map(|v| v.re as f32).collect()),
                Some(y.iter().map(|v| v.im as f32).collect()),
            ],
            trigger_time: crate::emulator::lecroy::NO_TRIGGER_TIME,
            edge_period_s: None,
        };
        let mut recording = state.recording(&self.model, &request, 1);
        recording.push(capture);
        state.complete(&request, recording, vec![0.0], false);
        let acquisition = state
            .acquisition
            .take()
            .ok_or_else(|| SceneError::Synthesis("the scope recorded nothing".into()))?;
        let mut recorded = acquisition.channels.into_iter().take(2).flatten();
        let (Some(i), Some(q)) = (recorded.next(), recorded.next()) else {
            return Err(SceneError::Synthesis(
                "the scope recorded fewer than two channels (I on C1, Q on C2)".into(),
            ));
        };
        let single = |v: f64| f64::from(v as f32);
        Ok(OfflineRecord {
            vertical_gain: [single(i.gain_word), single(q.gain_word)],
            vertical_offset: [single(i.offset_v), single(q.offset_v)],
            i: i.values,
            q: q.values,
            sample_rate: acquisition.sample_rate,
            first_point_s: acquisition.first_point_s,
        })
    }
}
