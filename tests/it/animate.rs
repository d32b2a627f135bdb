//! Headless animations: a rule-based scene rendered to a GIF decodes, with the requested frames, size and
//! both species' colours, and the file appears only whole.

use crate::common;

use coevo::io::Existing;
use coevo::run::animate::{animate, AnimateOptions, CAPTION};
use coevo::scene::{Boundary, Policy};
use coevo::sim::Simulation;

fn rgb(c: [f32; 3]) -> [u8; 3] {
    c.map(|v| (v * 255.0).round() as u8)
}

#[test]
fn a_rule_based_scene_renders_to_a_gif_with_both_species() {
    let mut scene = common::scene(3, 20, Policy::FleeNearest, Boundary::Periodic);
    scene.species[0].policy = Policy::ChaseNearest;
    let colours: Vec<[u8; 3]> = scene.species.iter().map(|s| rgb(s.colour)).collect();
    let mut sim = Simulation::new(scene);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("clip.gif");
    let opts = AnimateOptions {
        steps: 24,
        steps_per_frame: 3,
        trails: true,
        size: 160,
        title: "test".into(),
        progress: false,
    };
    let summary = animate(&mut sim, &opts, &path, Existing::Refuse).unwrap();
    assert_eq!(summary.frames, 24 / 3 + 1);
    assert!(summary.polarization.is_finite() && (0.0..=1.0).contains(&summary.milling));

    let mut options = gif::DecodeOptions::new();
    options.set_color_output(gif::ColorOutput::Indexed);
    let mut decoder = options.read_info(std::fs::File::open(&path).unwrap()).unwrap();
    let (w, h) = (decoder.width() as usize, decoder.height() as usize);
    assert_eq!((w, h), (160, 160 + CAPTION as usize));
    let palette = decoder.global_palette().unwrap().to_vec();
    let entry = |c: [u8; 3]| (0..palette.len() / 3).find(|&i| palette[3 * i..3 * i + 3] == c).map(|i| i as u8);
    let species: Vec<u8> = colours.iter().map(|&c| entry(c).expect("each species' colour is in the palette")).collect();
    // Composite the frames (unchanged pixels are transparent) and look for both colours in every one.
    let mut canvas = vec![0u8; w * h];
    let mut frames = 0;
    while let Some(frame) = decoder.read_next_frame().unwrap() {
        assert_eq!((frame.width as usize, frame.height as usize), (w, h), "whole-canvas frames");
        for (c, &i) in canvas.iter_mut().zip(frame.buffer.iter()) {
            if Some(i) != frame.transparent {
                *c = i;
            }
        }
        for s in &species {
            assert!(canvas.iter().filter(|&&i| i == *s).count() > 10, "frame {frames}: species colour {s} drawn");
        }
        frames += 1;
    }
    assert_eq!(frames, summary.frames);

    // An existing file is refused without being touched, and no temporary file is left.
    let before = std::fs::read(&path).unwrap();
    let mut sim = Simulation::new(common::scene(1, 5, Policy::Random, Boundary::Walls));
    let err = animate(&mut sim, &opts, &path, Existing::Refuse).unwrap_err().to_string();
    assert!(err.contains("clip.gif"), "{err}");
    assert_eq!(std::fs::read(&path).unwrap(), before);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}
