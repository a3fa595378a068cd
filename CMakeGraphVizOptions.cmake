# SPDX-License-Identifier: Apache-2.0
# What `cmake --graphviz` draws (scripts/architecture_graph, the picture in
# docs/architecture.md): the project's libraries and how they link, without
# tests, evaluation and benchmark programs or third-party libraries.
set(GRAPHVIZ_GRAPH_NAME "tinyline")
set(GRAPHVIZ_EXECUTABLES FALSE)
set(GRAPHVIZ_EXTERNAL_LIBS FALSE)
set(GRAPHVIZ_GENERATE_PER_TARGET FALSE)
set(GRAPHVIZ_GENERATE_DEPENDERS FALSE)
set(GRAPHVIZ_IGNORE_TARGETS "test" "testing" "bench" "fuzz" "layering" "eval" "^tinyline::")
