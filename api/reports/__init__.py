"""Human-readable reports (HTML) rendered from results."""
