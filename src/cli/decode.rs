//! `mocomp decode IN.mcv -o OUT.y4m`: a stream back to pictures.

use std::path::PathBuf;

use anyhow::{Context, Result};

use crate::codec::decoder::Decoder;
use crate::io::y4m::{Y4mInfo, Y4mWriter};
use crate::io::{open_input, OutputFile};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The stream (`-` for standard input).
    pub input: PathBuf,
    /// The Y4M to write (`-` for standard output, to pipe into ffmpeg or
    /// ffplay).
    #[arg(short, long, value_name = "OUT.y4m")]
    pub output: PathBuf,
}

pub fn run(args: &Args) -> Result<()> {
    let input = args.input.display().to_string();
    let reader = std::io::BufReader::new(open_input(&args.input).with_context(|| input.clone())?);
    let mut decoder = Decoder::new(reader).with_context(|| input.clone())?;
    let seq = *decoder.sequence();
    let info = Y4mInfo::for_sequence(&seq);
    let mut out = OutputFile::create(&args.output).with_context(|| args.output.display().to_string())?;
    {
        let mut writer = Y4mWriter::new(&mut out, &info)?;
        while let Some(frame) = decoder
            .next_frame()
            .with_context(|| format!("{input}: frame {}", decoder.frames_decoded()))?
        {
            writer.write_frame(&frame)?;
        }
    }
    out.commit().with_context(|| args.output.display().to_string())?;
    Ok(())
}
