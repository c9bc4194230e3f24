//! The run whose pipeline `pick`'s check chooses: every frame rendered first (R_s, D
//! and the seen emission, nothing denoised), then the check, which denoises the frames
//! both ways and returns the chosen image. What each step costs goes where a frame of
//! an animation would pay it: the chosen pipeline's denoising of the target frame to
//! `frame_denoise` (of the earlier frames to `frames`: they are frames too), the rest
//! of the check to `check` (once per sequence, as the pilot).

use std::time::Instant;

use super::*;

impl Run<'_> {
    /// Steps 2–4 with the pipeline picked (`Options::pick`; the difference predictor
    /// through OIDN on every frame).
    pub(super) fn picked(
        &self,
        choice: Choice,
        mut timings: Timings,
    ) -> Result<Regularized, RegularizeError> {
        let (frames, invalid_samples) = self.raw_frames(&mut timings);
        let (w, h) = (frames[0].source.width, frames[0].source.height);

        let started = Instant::now();
        let maps = self.reprojections(w, h);
        let mean_frames = mean_frames(&maps, w * h);
        let reprojecting = started.elapsed().as_secs_f64();
        self.bar.set_message("picking the pipeline");
        let checked = pick::check(&CheckInput {
            scene: self.scene,
            shot: self.shot,
            frames: &frames,
            maps: &maps,
            w_a: self.opts.w_a,
        })
        .map_err(RegularizeError::Denoise)?;
        timings.check = checked.check.seconds;
        timings.frame_denoise += checked.own_target_seconds;
        timings.frames += checked.own_seconds + checked.check.seconds + reprojecting;
        // The reprojection serves only the sequence pipelines.
        match checked.blended {
            Some(_) => timings.denoise_and_predict += reprojecting,
            None => timings.check += reprojecting,
        }
        self.bar.finish_and_clear();
        let first = frames.into_iter().next().expect("frame 0 is rendered");
        let blended = checked.blended.unwrap_or_else(|| Image {
            pixels: vec![[0.0; 3]; w * h],
            ..first.difference.clone()
        });
        Ok(Regularized {
            predicted: checked.image,
            source: checked.source,
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
            pipeline_check: Some(checked.check),
        })
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
            });
            self.bar.inc(1);
        }
        (frames, invalid_samples)
    }
}
