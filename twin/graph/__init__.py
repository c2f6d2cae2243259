"""The graph world model: vocabulary, RDF terms, the store, the import (records -> triples), statistics."""
