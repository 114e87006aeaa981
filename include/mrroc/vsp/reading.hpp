#pragma once
/// @file
/// The sensor reading types now live in the message layer; this header keeps old includes working.
#include "mrroc/msg/sensor_reading.hpp"  // IWYU pragma: export
