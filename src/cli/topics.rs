//! `proprioscope topics FILE`: what a robot recording holds, and the
//! topics `estimate` would take from it.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Result;
use proprioscope::io::recording::{self, TRUTH_POINT_TOPIC, TRUTH_TOPIC};

use super::TopicArgs;

/// Options of `topics`.
#[derive(Debug, clap::Args)]
pub struct TopicsArgs {
    /// A robot recording (`.mcap`, ROS 1 `.bag`).
    pub recording: PathBuf,
    /// A choice to check (as `estimate` takes it).
    #[command(flatten)]
    pub topics: TopicArgs,
}

/// Runs the command.
pub fn run(args: &TopicsArgs) -> Result<()> {
    let bytes = recording::read_bytes(&args.recording)?;
    let index = recording::index(&args.recording, &bytes)?;
    let mut out = String::new();
    let total: usize = index.topics.iter().map(|t| t.count).sum();
    writeln!(
        out,
        "{} ({}): {} topics, {total} messages",
        args.recording.display(),
        index.container,
        index.topics.len()
    )?;
    let w = index
        .topics
        .iter()
        .map(|t| t.topic.chars().count())
        .max()
        .unwrap_or(0)
        .max(5);
    let tw = index
        .topics
        .iter()
        .map(|t| t.message_type.chars().count())
        .max()
        .unwrap_or(0)
        .max(4);
    writeln!(
        out,
        "{:<w$}  {:<tw$} {:>8} {:>9}  time from; float arrays",
        "topic", "type", "messages", "rate Hz"
    )?;
    for t in &index.topics {
        let rate = t.rate_hz().map_or_else(|| "-".to_owned(), |r| format!("{r:.1}"));
        let detail = if let Err(why) = &t.definition {
            format!("not decodable: {why}")
        } else {
            {
                let arrays: Vec<String> = t.float_arrays().iter().map(|(f, n)| format!("{f}[{n}]")).collect();
                let names = if t.has_names() { ", joint names" } else { "" };
                format!(
                    "{}; {}{names}",
                    t.stamp_source(),
                    if arrays.is_empty() {
                        "-".to_owned()
                    } else {
                        arrays.join(" ")
                    }
                )
            }
        };
        writeln!(
            out,
            "{:<w$}  {:<tw$} {:>8} {:>9}  {detail}",
            t.topic, t.message_type, t.count, rate
        )?;
    }
    let truth = index.topics.iter().any(|t| t.topic == TRUTH_TOPIC)
        && index.topics.iter().any(|t| t.topic == TRUTH_POINT_TOPIC);
    if truth {
        writeln!(out, "truth: {TRUTH_TOPIC} and {TRUTH_POINT_TOPIC}")?;
    }
    match index.mapping(&args.topics.choice()) {
        Ok(mapping) => writeln!(out, "frames from: {mapping}")?,
        Err(e) => writeln!(out, "no frames yet: {e}")?,
    }
    outln!("{}", out.trim_end());
    Ok(())
}
