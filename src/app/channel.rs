//! Looking up a channel of a display configuration by the index the command line gives.

use crate::display::{Channel, DisplayConfig};
use crate::{Error, Result};

/// Channel `index` of `cfg` (`name` names the configuration in the error), or an error for
/// `--channel` saying how many channels there are.
pub fn channel<'a>(cfg: &'a DisplayConfig, name: &str, index: usize) -> Result<&'a Channel> {
    cfg.channels.get(index).ok_or_else(|| {
        Error::invalid(
            "--channel",
            format!(
                "{name} has {} channel(s), asked for index {index}",
                cfg.channels.len()
            ),
        )
    })
}
