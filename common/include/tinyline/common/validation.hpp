// SPDX-License-Identifier: Apache-2.0
// Validation, the older {valid, reason} form of a parameter check's outcome,
// now lives beside Status in status.hpp; this header stays for its last users.
#pragma once

#include <tinyline/common/status.hpp>
