#pragma once
/// @file
/// The EDP's instruction and reply types now live in the message layer; this header keeps old
/// includes working.
#include "mrroc/msg/edp_instruction.hpp"  // IWYU pragma: export
