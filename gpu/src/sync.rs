//! The host's semaphores a submission waits on and signals.
//!
//! Waits are at every pipeline stage. Each value is used by timeline
//! semaphores and ignored for binary ones, as `VkTimelineSemaphoreSubmitInfo`
//! specifies.

use ash::vk;

use crate::error::{GpuError as Error, Result};

/// One semaphore srug's first submission waits on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SemaphoreWait {
    /// The semaphore (binary or timeline).
    pub semaphore: vk::Semaphore,
    /// The value to wait for (timeline semaphores; ignored for binary ones).
    pub value: u64,
}

/// One semaphore srug's last submission signals.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SemaphoreSignal {
    /// The semaphore (binary or timeline).
    pub semaphore: vk::Semaphore,
    /// The value to signal (timeline semaphores; ignored for binary ones).
    pub value: u64,
}

/// Semaphores a host passes with a call: srug's work waits on `wait` (at
/// every stage) and signals `signal` when done.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct HostSync {
    /// Waited on by the call's first submission.
    pub wait: Vec<SemaphoreWait>,
    /// Signalled by the call's last submission.
    pub signal: Vec<SemaphoreSignal>,
}

impl HostSync {
    /// Checks for null handles; `what` names the call.
    pub fn check(&self, what: &str) -> Result<()> {
        let null = self.wait.iter().map(|w| w.semaphore).chain(self.signal.iter().map(|s| s.semaphore));
        if null.into_iter().any(|s| s == vk::Semaphore::null()) {
            return Err(Error::invalid(what, "a semaphore is VK_NULL_HANDLE"));
        }
        Ok(())
    }

    /// The waits alone (for a call's first submission).
    pub fn waits_only(&self) -> Self {
        Self { wait: self.wait.clone(), signal: Vec::new() }
    }

    /// The signals alone (for a call's last submission).
    pub fn signals_only(&self) -> Self {
        Self { wait: Vec::new(), signal: self.signal.clone() }
    }
}
