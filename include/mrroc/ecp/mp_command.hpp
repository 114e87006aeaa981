#pragma once
/// @file
/// The MP-ECP command and reply types now live in the message layer; this header keeps old includes
/// working.
#include "mrroc/msg/mp_command.hpp"  // IWYU pragma: export
