//! `mocomp samples --out DIR`: the synthetic samples with exact flow.

use std::path::PathBuf;

use anyhow::{bail, Result};

use crate::synth::{standard_scenes, write_sample};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Folder to write into (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Only these samples (by name; repeatable). Default: all.
    #[arg(long)]
    pub only: Vec<String>,
    /// Also write the backward flows (frame t to t - 1).
    #[arg(long)]
    pub backward: bool,
}

pub fn run(args: &Args) -> Result<()> {
    let scenes = standard_scenes();
    for name in &args.only {
        if !scenes.iter().any(|s| &s.name == name) {
            let names: Vec<_> = scenes.iter().map(|s| s.name.as_str()).collect();
            bail!("no sample named '{name}'; there are: {}", names.join(", "));
        }
    }
    for spec in scenes
        .iter()
        .filter(|s| args.only.is_empty() || args.only.contains(&s.name))
    {
        let written = write_sample(spec, &args.out, args.backward)?;
        outln!(
            "{}: {}x{}, {} frames; {} .flo files in {}",
            written.y4m.display(),
            spec.width,
            spec.height,
            spec.frames,
            written.flow_files,
            written.flow_dir.display()
        )?;
    }
    Ok(())
}
