"""The four stages of LTC-Mapping as pure functions over arrays (modeling, association,
integration, maintenance), and the mapper that applies their decisions to the map and logs them."""
