//! The handle registry. A handle given to C is a number, not an address: each
//! call looks it up here, so destroyed, foreign or made-up handles are errors
//! instead of undefined behaviour. Numbers count up and are never reused.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, LazyLock, Mutex, MutexGuard, PoisonError};

use crate::{srug_status, Failure, FfiResult};

/// A live object behind a handle.
#[derive(Clone)]
pub(crate) enum Object {
    Context(Arc<crate::context::Context>),
    Scene(Arc<Mutex<crate::scene::SceneObject>>),
    Environment(Arc<crate::environment::EnvironmentObject>),
    Renderer(Arc<Mutex<crate::renderer::RendererObject>>),
}

impl Object {
    fn kind(&self) -> &'static str {
        match self {
            Object::Context(_) => "context",
            Object::Scene(_) => "scene",
            Object::Environment(_) => "environment",
            Object::Renderer(_) => "renderer",
        }
    }
}

struct Entry {
    object: Object,
    /// The owning context's number (0 for contexts).
    context: u64,
}

static REGISTRY: LazyLock<Mutex<HashMap<u64, Entry>>> = LazyLock::new(|| Mutex::new(HashMap::new()));
static NEXT: AtomicU64 = AtomicU64::new(1);

/// Handles are spaced and offset so that small integers and NULL are never handles.
const SPACING: u64 = 16;
const OFFSET: u64 = 0x5000;

fn registry() -> MutexGuard<'static, HashMap<u64, Entry>> {
    // Nothing panics while the registry is locked; recover from poisoning anyway.
    REGISTRY.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Registers an object owned by `context` (0 for a context) and returns its handle number.
pub(crate) fn insert(object: Object, context: u64) -> u64 {
    let id = OFFSET + SPACING * NEXT.fetch_add(1, Ordering::Relaxed);
    registry().insert(id, Entry { object, context });
    id
}

/// The object behind `id`, which must be of kind `kind`; and its context.
pub(crate) fn get(id: u64, kind: &'static str) -> FfiResult<(Object, u64)> {
    match registry().get(&id) {
        Some(e) if e.object.kind() == kind => Ok((e.object.clone(), e.context)),
        Some(e) => Err(Failure::new(
            srug_status::SRUG_ERROR_INVALID_HANDLE,
            format!("the handle is a {}, not a {kind}", e.object.kind()),
        )),
        None => Err(Failure::new(
            srug_status::SRUG_ERROR_INVALID_HANDLE,
            format!("{id:#x} is not a live {kind} handle (destroyed, or not made by srug)"),
        )),
    }
}

/// Removes `id` (of kind `kind`). A context with live objects stays.
pub(crate) fn remove(id: u64, kind: &'static str) -> FfiResult {
    let mut reg = registry();
    match reg.get(&id) {
        Some(e) if e.object.kind() == kind => {}
        _ => {
            drop(reg);
            return get(id, kind).map(|_| ());
        }
    }
    if kind == "context" {
        let children = reg.values().filter(|e| e.context == id).count();
        if children > 0 {
            return Err(Failure::new(
                srug_status::SRUG_ERROR_WRONG_ORDER,
                format!("the context still has {children} live object(s); destroy them first"),
            ));
        }
    }
    let removed = reg.remove(&id);
    drop(reg);
    // The object (and its GPU memory) is released here, outside the registry lock.
    drop(removed);
    Ok(())
}

/// How many handles are alive.
pub(crate) fn live() -> usize {
    registry().len()
}

/// A handle number from a C pointer.
pub(crate) fn id_of<T>(p: *const T) -> FfiResult<u64> {
    if p.is_null() {
        return Err(Failure::new(srug_status::SRUG_ERROR_NULL_POINTER, "the handle is NULL"));
    }
    Ok(p as usize as u64)
}

/// A C pointer from a handle number (never dereferenced).
pub(crate) fn ptr_of<T>(id: u64) -> *mut T {
    id as usize as *mut T
}

/// Locks a handle's object. A lock poisoned by a caught panic is recovered:
/// the panicking call already returned `SRUG_ERROR_PANIC`, and every later
/// call validates what it uses, so the handle stays usable rather than
/// failing forever.
pub(crate) fn lock<T>(m: &Mutex<T>) -> FfiResult<MutexGuard<'_, T>> {
    Ok(m.lock().unwrap_or_else(|poisoned| {
        m.clear_poison();
        poisoned.into_inner()
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A handle whose lock a panic poisoned is usable by the next call.
    #[test]
    fn a_panic_does_not_poison_a_handle_forever() {
        let m = Mutex::new(5);
        let caught = std::panic::catch_unwind(|| {
            let _held = m.lock();
            panic!("a bug inside a call");
        });
        assert!(caught.is_err() && m.is_poisoned());
        assert!(matches!(lock(&m).map(|g| *g), Ok(5)));
        assert!(!m.is_poisoned(), "the poison is cleared");
    }
}
