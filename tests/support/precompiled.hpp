#pragma once
/// @file
/// Headers nearly every test parses: compiled once into the precompiled header of
/// mrroc_test_pch and reused by every test executable (tests/CMakeLists.txt), which saves about a
/// third of a test's compile time. Only third-party and standard headers: our own change often.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>
