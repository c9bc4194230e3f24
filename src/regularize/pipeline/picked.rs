//! The run whose pipeline `pick`'s check chooses: every frame rendered first (R_s, D
//! and the seen emission, nothing denoised), the check on the central window, then the
//! chosen pipeline on the whole frames. What each step costs goes where a frame of an
//! animation would pay it: the target frame's own denoising to `frame_denoise`, the
//! check and the other pipelines' denoising to `check` (once per sequence, as the
//! pilot).

use std::time::Instant;

use super::*;
use crate::denoise::OidnError;
use crate::image::merge::mean_by_spp;

impl Run<'_> {
    /// Steps 2–4 with the pipeline picked (`Options::pick`; the difference predictor
    /// through OIDN on every frame).
    pub(super) fn picked(
        &self,
        choice: Choice,
        mut timings: Timings,
    ) -> Result<Regularized, RegularizeError> {
        let (scene, shot) = (self.scene, self.shot);
        let failed = RegularizeError::Denoise;
        let (mut frames, mut invalid_samples) = self.raw_frames(&mut timings);
        let (w, h) = (frames[0].source.width, frames[0].source.height);

        let started = Instant::now();
        let maps = self.reprojections(w, h);
        let mean_frames = 1.0
            + maps
                .iter()
                .map(|m| m.iter().filter(|p| p.is_some()).count() as f64)
                .sum::<f64>()
                / (w * h) as f64;
        let reprojecting = started.elapsed().as_secs_f64();
        let check = pick::check(&CheckInput {
            scene,
            shot,
            frames: &frames,
            maps: &maps,
            w_a: self.opts.w_a,
        })
        .map_err(failed)?;
        timings.check = check.seconds;
        invalid_samples += self.top_up(&mut frames, &check, &mut timings);

        // The chosen pipeline on the whole frames: frame 0's denoising is the frame's
        // own, the earlier frames' is theirs (they are frames of the animation too).
        let mut own = 0.0;
        let mut denoise_frames = |f: &dyn Fn(&RawFrame) -> Result<Image, OidnError>| {
            let mut out = Vec::with_capacity(frames.len());
            for (k, frame) in frames.iter().enumerate() {
                let start = Instant::now();
                out.push(f(frame)?);
                let spent = start.elapsed().as_secs_f64();
                timings.frames += spent;
                if k == 0 {
                    own += spent;
                }
            }
            Ok::<_, OidnError>(out)
        };
        let oidn_plain =
            |f: &RawFrame| denoise::oidn(&f.plain(), Some(&f.seen), None, AuxUse::None);
        let blend = |images: &[Image]| {
            let refs: Vec<&[[f32; 3]]> = images.iter().map(|i| i.pixels.as_slice()).collect();
            as_image(w, h, temporal::blend(&refs, &maps, w, h, self.opts.w_a))
        };
        let zeros = as_image(w, h, vec![[0.0; 3]; w * h]);
        let (predicted, source, blended) = match check.chosen {
            Pipeline::Split => {
                let differences = denoise_frames(&|f: &RawFrame| {
                    denoise::oidn_signed(&f.difference, None, AuxUse::None)
                })
                .map_err(failed)?;
                let start = Instant::now();
                let f0 = &frames[0];
                let source = denoise::oidn(&f0.source, Some(&f0.seen), None, AuxUse::None)
                    .map_err(failed)?;
                own += start.elapsed().as_secs_f64();
                let start = Instant::now();
                let blended = blend(&differences);
                let predicted = pick::sum(&source, &blended);
                timings.denoise_and_predict += start.elapsed().as_secs_f64();
                (predicted, source, blended)
            }
            Pipeline::Control => {
                let controls = denoise_frames(&oidn_plain).map_err(failed)?;
                let start = Instant::now();
                let blended = blend(&controls);
                timings.denoise_and_predict += start.elapsed().as_secs_f64();
                (blended.clone(), frames[0].source.clone(), blended)
            }
            Pipeline::PlainOidn => {
                let start = Instant::now();
                let image = oidn_plain(&frames[0]).map_err(failed)?;
                own += start.elapsed().as_secs_f64();
                (image, frames[0].source.clone(), zeros.clone())
            }
            Pipeline::Plain => (frames[0].plain(), frames[0].source.clone(), zeros.clone()),
        };
        // The reprojection serves only the sequence pipelines.
        match check.chosen {
            Pipeline::Split | Pipeline::Control => timings.denoise_and_predict += reprojecting,
            Pipeline::PlainOidn | Pipeline::Plain => timings.check += reprojecting,
        }
        timings.frame_denoise += own;
        self.bar.finish_and_clear();
        let first = frames.into_iter().next().expect("frame 0 is rendered");
        Ok(Regularized {
            predicted,
            source,
            raw_gradient: first.difference,
            gradient: blended.clone(),
            blended,
            seen_emission: Some(first.seen),
            albedos: choice.albedos,
            c_beta: None,
            fallbacks: 0,
            mean_frames,
            frames_rendered: self.frames.len(),
            timings,
            invalid_samples,
            pilot: choice.pilot,
            pilot_unaffordable: choice.pilot_unaffordable,
            oidn_check: None,
            pipeline_check: Some(check),
        })
    }

    /// The samples the chosen pipeline's cheaper denoising buys, rendered and merged
    /// into the frames that pipeline uses (the target frame's to `target_frame`); the
    /// invalid samples met.
    fn top_up(&self, frames: &mut [RawFrame], check: &PipelineCheck, timings: &mut Timings) -> u64 {
        let saved = &check.denoise_seconds;
        let mut invalid_samples = 0;
        for (k, frame) in frames.iter_mut().enumerate() {
            let seconds = match k {
                0 => saved.saved_on_target(check.chosen),
                _ => saved.saved_on_earlier(check.chosen),
            };
            let n = self.shot.spp;
            let per_spp = frame.render_seconds / n as f64;
            let extra = (seconds / per_spp.max(1e-12)).floor().min(1e6) as u32;
            if extra == 0 {
                continue;
            }
            // Far from every seed the run uses (32 bits, as Mitsuba's).
            let seed = self.shot.seed.wrapping_add(0x5bd1_e995 + k as u64) & 0xffff_ffff;
            let to_world = self.frames[k];
            let r = self.render_frame(to_world, seed, self.albedos.source, Some(extra), true);
            invalid_samples += r.stats.invalid_samples;
            let start = Instant::now();
            let mut seen = r.seen_emission.expect("asked for");
            let mut frame_shot = self.shot.clone();
            frame_shot.camera.to_world = to_world;
            aovs::sharpen_seen_emission(self.scene, &frame_shot, &mut seen);
            let (a, b) = (n as u64, extra as u64);
            frame.source = mean_by_spp(&[(&frame.source, a), (&r.image, b)]);
            if let Some(d) = &r.gradient {
                frame.difference = mean_by_spp(&[(&frame.difference, a), (d, b)]);
            }
            frame.seen = mean_by_spp(&[(&frame.seen, a), (&seen, b)]);
            let spent = r.stats.seconds + start.elapsed().as_secs_f64();
            timings.frames += spent;
            if k == 0 {
                timings.target_frame += spent;
            }
        }
        invalid_samples
    }

    /// Step 2 without denoising: each frame's R_s, D and sharpened seen emission, the
    /// target frame first; their seconds go to `timings` (the target frame's render to
    /// `target_frame`, its sharpening to `frame_denoise`).
    fn raw_frames(&self, timings: &mut Timings) -> (Vec<RawFrame>, u64) {
        let mut frames = Vec::with_capacity(self.frames.len());
        let mut invalid_samples = 0;
        for (k, &to_world) in self.frames.iter().enumerate() {
            self.bar.set_message(format!("frame k = {k}"));
            let seed = self.shot.seed.wrapping_add(k as u64);
            let r = self.render_frame(to_world, seed, self.albedos.source, None, true);
            timings.frames += r.stats.seconds;
            invalid_samples += r.stats.invalid_samples;
            let start = Instant::now();
            let mut seen = r.seen_emission.expect("asked for");
            let mut frame_shot = self.shot.clone();
            frame_shot.camera.to_world = to_world;
            aovs::sharpen_seen_emission(self.scene, &frame_shot, &mut seen);
            let spent = start.elapsed().as_secs_f64();
            timings.frames += spent;
            if k == 0 {
                timings.target_frame = r.stats.seconds;
                timings.frame_denoise = spent;
            }
            let difference = r.gradient.unwrap_or_else(|| Image {
                pixels: vec![[0.0; 3]; r.image.pixels.len()],
                ..r.image.clone()
            });
            frames.push(RawFrame {
                source: r.image,
                difference,
                seen,
                render_seconds: r.stats.seconds,
            });
            self.bar.inc(1);
        }
        (frames, invalid_samples)
    }
}
