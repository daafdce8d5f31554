//! The C ABI misused as a careless caller would (issue 39's matrix): each
//! call fails with the status the header documents, writes nothing it was
//! not asked to on failure, and leaves the handle working for the next call.

#![allow(clippy::unwrap_used, clippy::expect_used, reason = "test code: a failure should stop the test")]

use std::ffi::{c_char, CStr};
use std::ptr::{null, null_mut};

use srug_c::*;

fn last_error() -> String {
    let mut buf = vec![0 as c_char; 1024];
    // SAFETY: a local buffer of the stated length.
    unsafe { srug_last_error(buf.as_mut_ptr(), buf.len(), null_mut()) };
    // SAFETY: NUL-terminated by srug_last_error.
    unsafe { CStr::from_ptr(buf.as_ptr()) }.to_string_lossy().into_owned()
}

fn ok(s: srug_status) {
    assert_eq!(s, srug_status::SRUG_OK, "{}", last_error());
}

/// `s` is `want`, and the last error names `words`.
fn refused(s: srug_status, want: srug_status, words: &[&str]) {
    let e = last_error();
    assert_eq!(s, want, "{e}");
    for w in words {
        assert!(e.contains(w), "{w:?} not in {e:?}");
    }
}

/// A context with validation, a 3000-Gaussian demo scene and a 32×16
/// renderer that has rendered once.
struct Rig {
    ctx: *mut srug_context,
    scene: *mut srug_scene,
    r: *mut srug_renderer,
}

impl Rig {
    fn new() -> Self {
        let (mut ctx, mut scene, mut r) = (null_mut(), null_mut(), null_mut());
        let (eye, target, up) = ([-30.0f32, -2.0, 6.0], [10.0f32, -2.0, 2.0], [0.0f32, 0.0, 1.0]);
        // SAFETY: out-pointers to locals; arrays of the stated lengths.
        unsafe {
            ok(srug_context_create(null(), SRUG_CONTEXT_VALIDATION, &mut ctx));
            ok(srug_scene_create_demo(ctx, 3000, 11, &mut scene));
            ok(srug_renderer_create(ctx, 32, 16, 0, &mut r));
            ok(srug_renderer_set_camera_look_at(r, eye.as_ptr(), target.as_ptr(), up.as_ptr(), 80.0));
            ok(srug_renderer_render(r, scene));
        }
        Self { ctx, scene, r }
    }

    /// The renderer still renders and reads back.
    fn still_works(&self) {
        let mut px = vec![0u8; 32 * 16 * 4];
        // SAFETY: handles from `new`; a buffer of the stated length.
        unsafe {
            ok(srug_renderer_render(self.r, self.scene));
            ok(srug_renderer_read_image(self.r, SRUG_FORMAT_RGBA8_SRGB, px.as_mut_ptr().cast(), px.len(), 0));
        }
        assert!(px.iter().any(|v| *v != 0), "the frame read back is empty");
    }
}

impl Drop for Rig {
    fn drop(&mut self) {
        let mut count = usize::MAX;
        // SAFETY: handles from `new`, destroyed once.
        unsafe {
            ok(srug_context_take_validation_messages(self.ctx, &mut count, null_mut(), 0));
            ok(srug_renderer_destroy(self.r));
            ok(srug_scene_destroy(self.scene));
            ok(srug_context_destroy(self.ctx));
        }
        assert_eq!(count, 0, "validation messages");
    }
}

#[test]
fn sizes_strides_and_counts_that_overflow_are_refused() {
    let rig = Rig::new();
    let mut dst = vec![0xA5u8; 32 * 16 * 4];
    // SAFETY: a buffer of the stated length; the stride is what is wrong.
    let s = unsafe {
        srug_renderer_read_image(rig.r, SRUG_FORMAT_RGBA8_SRGB, dst.as_mut_ptr().cast(), dst.len(), usize::MAX)
    };
    refused(s, srug_status::SRUG_ERROR_INVALID_ARGUMENT, &["row_stride", "overflows"]);
    assert!(dst.iter().all(|v| *v == 0xA5), "nothing is written on failure");
    let mut scene = null_mut();
    for count in [1usize << 40, usize::MAX] {
        // SAFETY: an out-pointer to a local.
        let s = unsafe { srug_scene_create_demo(rig.ctx, count, 1, &mut scene) };
        refused(s, srug_status::SRUG_ERROR_INVALID_ARGUMENT, &["Gaussians", "limit"]);
        assert!(scene.is_null(), "no scene on failure");
    }
    rig.still_works();
}

#[test]
fn documented_ranges_are_enforced_and_poisonous_settings_refused() {
    let rig = Rig::new();
    let (eye, target) = ([0.0f32, 0.0, 2.0], [10.0f32, 0.0, 2.0]);
    let along = [1.0f32, 0.0, 0.0];
    let up = [0.0f32, 0.0, 1.0];
    let pose = [1.0f32, 0., 0., 0., 0., 0., -1., 0., 0., 1., 0., 0., 0., 0., 2., 1.];
    let view = [1.0f32, 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1.];
    // gluPerspective form with a finite x scale whose focal length overflows f32.
    let projection = [3e38f32, 0., 0., 0., 0., 2., 0., 0., 0., 0., -1.002, -1., 0., 0., -0.2002, 0.];
    // SAFETY: the renderer from `Rig`; arrays of the stated lengths.
    unsafe {
        let s = srug_renderer_set_shadow(rig.r, 15, 20.0, 0.5);
        refused(s, srug_status::SRUG_ERROR_INVALID_ARGUMENT, &["resolution 15", "16..=16384"]);
        let s = srug_renderer_set_shadow(rig.r, 1024, 20.0, -1.0);
        refused(s, srug_status::SRUG_ERROR_INVALID_ARGUMENT, &["bias -1", "≥ 0"]);
        let s = srug_renderer_set_camera(rig.r, f32::INFINITY, 100.0, 16.0, 8.0, pose.as_ptr(), 0.01, 100.0);
        refused(s, srug_status::SRUG_ERROR_INVALID_ARGUMENT, &["fx is inf"]);
        let s = srug_renderer_set_camera_matrices(rig.r, view.as_ptr(), projection.as_ptr());
        refused(s, srug_status::SRUG_ERROR_INVALID_ARGUMENT, &["focal lengths", "finite and positive"]);
        let s = srug_renderer_set_camera_look_at(rig.r, eye.as_ptr(), target.as_ptr(), up.as_ptr(), 1e-40);
        refused(s, srug_status::SRUG_ERROR_INVALID_ARGUMENT, &["fov"]);
        let s = srug_renderer_set_camera_look_at(rig.r, eye.as_ptr(), target.as_ptr(), along.as_ptr(), 60.0);
        refused(s, srug_status::SRUG_ERROR_INVALID_ARGUMENT, &["parallel to the view direction"]);
        let s = srug_renderer_set_exposure(rig.r, 1e30, SRUG_TONE_MAP_ACES);
        refused(s, srug_status::SRUG_ERROR_INVALID_ARGUMENT, &["exposure_ev", "stops"]);
        ok(srug_renderer_set_preset(rig.r, c"balanced".as_ptr()));
    }
    rig.still_works();
}

#[test]
fn outputs_are_untouched_when_a_call_fails() {
    let rig = Rig::new();
    let mut count = 7usize;
    let mut seconds = -1.0f64;
    let mut short = [0x55 as c_char; 3];
    // SAFETY: handles from `Rig`; buffers of the stated lengths (or NULL, which is what is wrong).
    unsafe {
        let s = srug_context_take_validation_messages(rig.ctx, &mut count, null_mut(), 64);
        refused(s, srug_status::SRUG_ERROR_NULL_POINTER, &["buf"]);
        assert_eq!(count, 7, "count untouched");
        let s = srug_renderer_stage(rig.r, 0, null_mut(), 16, &mut seconds);
        refused(s, srug_status::SRUG_ERROR_NULL_POINTER, &["buf"]);
        assert_eq!(seconds, -1.0, "seconds untouched");
        let s = srug_renderer_stage(rig.r, 0, short.as_mut_ptr(), short.len(), &mut seconds);
        refused(s, srug_status::SRUG_ERROR_BUFFER_TOO_SMALL, &["bytes"]);
        assert_eq!(seconds, -1.0, "seconds untouched");
        assert_eq!(short[2], 0, "the name is cut and NUL-terminated");
        // The device name into a short buffer: the documented cut copy.
        let mut name = [0x55 as c_char; 5];
        let mut full = 0usize;
        let s = srug_context_device_name(rig.ctx, name.as_mut_ptr(), name.len(), &mut full);
        refused(s, srug_status::SRUG_ERROR_BUFFER_TOO_SMALL, &[]);
        let cut = CStr::from_ptr(name.as_ptr()).to_string_lossy().into_owned();
        assert!(cut.len() == 4 && full > 4, "cut {cut:?} of {full} bytes");
        let mut whole = vec![0 as c_char; full + 1];
        ok(srug_context_device_name(rig.ctx, whole.as_mut_ptr(), whole.len(), null_mut()));
        assert!(CStr::from_ptr(whole.as_ptr()).to_string_lossy().starts_with(&cut));
    }
    rig.still_works();
}
