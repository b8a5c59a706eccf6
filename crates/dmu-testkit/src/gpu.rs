//! The test binary's one device, and what tests expect of each adapter.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::OnceLock;

use dmu_render::wgpu;

use crate::{require, shout, skip, test_name};

/// The device every GPU test of a binary shares, with its adapter's description.
#[derive(Debug)]
pub struct Gpu {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
}

impl Gpu {
    /// Whether the device has `features`; where it lacks some, the part of a
    /// test that needs them [`skip`]s (a failure under `CI=true`).
    pub fn supports(&self, features: wgpu::Features) -> bool {
        let missing = features - self.device.features();
        if !missing.is_empty() {
            skip(format!("{} lacks {missing:?}", self.info.name));
        }
        missing.is_empty()
    }
}

/// The binary's device (`dmu_render::headless_device`, opened on first use),
/// or why there is none.
pub fn gpu() -> Result<&'static Gpu, String> {
    static GPU: OnceLock<Result<Gpu, String>> = OnceLock::new();
    GPU.get_or_init(|| {
        dmu_render::headless_device()
            .map(|(device, queue, info)| Gpu {
                device,
                queue,
                info,
            })
            .map_err(|e| format!("no Vulkan adapter ({e})"))
    })
    .as_ref()
    .map_err(Clone::clone)
}

/// Runs `body` on the binary's device, or [`skip`]s (a failure under
/// `CI=true`) where there is none.
pub fn with_gpu(body: impl FnOnce(&Gpu)) {
    GpuTest::new().run(body);
}

/// Adapters an expectation is declared for: a driver, and the beginning of its
/// version string.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Adapter {
    driver: &'static str,
    version: &'static str,
}

impl Adapter {
    /// Mesa's lavapipe (its driver reports itself as llvmpipe) of a version
    /// beginning with `mesa`, e.g. "Mesa 22.3".
    pub const fn lavapipe(mesa: &'static str) -> Self {
        Adapter {
            driver: "llvmpipe",
            version: mesa,
        }
    }

    fn matches(&self, info: &wgpu::AdapterInfo) -> bool {
        info.driver == self.driver && info.driver_info.starts_with(self.version)
    }
}

/// A GPU test's declaration: the features it needs and the adapters it is
/// known to fail on.
#[derive(Debug, Default)]
pub struct GpuTest {
    features: wgpu::Features,
    known_failures: Vec<(Adapter, &'static str)>,
}

impl GpuTest {
    pub fn new() -> Self {
        Self::default()
    }

    /// Features the whole test needs: without them it [`skip`]s.
    pub fn features(mut self, features: wgpu::Features) -> Self {
        self.features |= features;
        self
    }

    /// The test fails on `adapter` because of `bug` (a driver's, not ours): it
    /// runs there, its failure prints `EXPECTED FAILURE <test>: <bug>` and
    /// passes, and a pass fails, so the declaration goes once the driver is fixed.
    pub fn fails_on(mut self, adapter: Adapter, bug: &'static str) -> Self {
        self.known_failures.push((adapter, bug));
        self
    }

    /// Runs `body` on the binary's device as declared.
    pub fn run(self, body: impl FnOnce(&Gpu)) {
        require(gpu(), |gpu| {
            if !gpu.supports(self.features) {
                return;
            }
            let known = self
                .known_failures
                .iter()
                .find(|(a, _)| a.matches(&gpu.info));
            match known {
                None => body(gpu),
                Some((adapter, bug)) => {
                    let test = test_name();
                    let failed = catch_unwind(AssertUnwindSafe(|| body(gpu))).is_err();
                    assert!(
                        failed,
                        "{test} passed on {adapter:?} ({}), declared to fail there: {bug}",
                        gpu.info.driver_info
                    );
                    shout(&format!(
                        "EXPECTED FAILURE {test} on {}: {bug}",
                        gpu.info.driver_info
                    ));
                }
            }
        });
    }
}
