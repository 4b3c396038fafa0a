//! The simulated bench's scene, typed: set the scene, reseed its noise, read it back. The bench
//! speaks mock_lab's scene control protocol (JSON lines) to the in-process lab or to the bench
//! file's `[simulation] control` address; callers above `measure` (campaigns) name only these
//! methods and the scene types re-exported here, never the protocol or mock_lab.

use crate::measure::bench::in_use::Bench;
use serde_json::{json, Value};

pub(crate) use mock_lab::scene::{Chain, ChainPreset, Impairments, Scene, Target};

/// Why a request on the simulated bench's scene control failed (the text says it whole).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub(crate) enum SceneControlError {
    /// The bench is a bench file without a `[simulation] control` address (a real bench).
    #[error("the bench file has no [simulation] control address")]
    NoControl,
    /// The lab refused the request, or did not answer.
    #[error("{0}")]
    Refused(String),
}

impl Bench {
    /// Replaces the simulated scene (validated by the lab; its noise restarts from the scene's
    /// seed).
    pub(crate) async fn set_scene(&self, scene: &Scene) -> Result<(), SceneControlError> {
        self.scene_request(&json!({"cmd": "set", "scene": scene}))
            .await
            .map(|_| ())
    }

    /// Restarts the simulated noise generator from `seed` (a lab that cannot, an older mock_lab,
    /// refuses and changes nothing).
    pub(crate) async fn reseed(&self, seed: u64) -> Result<(), SceneControlError> {
        self.scene_request(&json!({"cmd": "seed", "seed": seed}))
            .await
            .map(|_| ())
    }

    /// The simulated scene as it is now.
    pub(crate) async fn scene(&self) -> Result<Scene, SceneControlError> {
        let reply = self.scene_request(&json!({"cmd": "get"})).await?;
        serde_json::from_value::<Scene>(reply["scene"].clone())
            .map_err(|e| SceneControlError::Refused(format!("`get` gave no scene: {e}")))
    }

    async fn scene_request(&self, request: &Value) -> Result<Value, SceneControlError> {
        match self.control(request).await {
            Some(Ok(v)) => Ok(v),
            Some(Err(e)) => Err(SceneControlError::Refused(e)),
            None => Err(SceneControlError::NoControl),
        }
    }
}
