#pragma once
/// @file
/// The third-party and standard headers most of mrroc's library files parse: compiled once into
/// the precompiled header of mrroc_precompiled and reused by every library target
/// (mrroc_precompiled() in src/CMakeLists.txt). Only headers that do not change with our code.

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include <fmt/format.h>
