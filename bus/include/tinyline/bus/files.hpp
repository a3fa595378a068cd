// SPDX-License-Identifier: Apache-2.0
// The project's one helper for reading and writing files lives in common, so
// that algorithm cores (which never see the bus) read their inputs the same
// way: <tinyline/common/files.hpp>.
#pragma once

#include <tinyline/common/files.hpp>
